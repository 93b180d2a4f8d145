//! Border handling shared by the filters: OpenCV's default `BORDER_REFLECT_101`
//! (`gfedcb|abcdefgh|gfedcba`), so that outputs match OpenCV's at the image edges too.

/// Maps a possibly out-of-range index to `0..n` by reflection without repeating the edge pixel.
/// `n` must be positive; a one-pixel axis maps everything to 0.
#[inline]
pub(crate) fn reflect101(i: isize, n: usize) -> usize {
    let n = n as isize;
    if n <= 1 {
        return 0;
    }
    let period = 2 * (n - 1);
    let mut i = i.rem_euclid(period);
    if i >= n {
        i = period - i;
    }
    i as usize
}

/// Copies `row` into `out` with `pad` reflected pixels on each side (`out.len() == row.len() + 2 pad`).
pub(crate) fn pad_row<T: Copy>(row: &[T], pad: usize, out: &mut Vec<T>) {
    out.clear();
    let n = row.len();
    if n == 0 {
        return;
    }
    out.extend((0..pad).map(|k| row[reflect101(k as isize - pad as isize, n)]));
    out.extend_from_slice(row);
    out.extend((0..pad).map(|k| row[reflect101((n + k) as isize, n)]));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reflect101_matches_opencv() {
        let got: Vec<usize> = (-3..8).map(|i| reflect101(i, 5)).collect();
        assert_eq!(got, vec![3, 2, 1, 0, 1, 2, 3, 4, 3, 2, 1]);
        assert_eq!(reflect101(-7, 1), 0);
        let mut out = Vec::new();
        pad_row(&[1u8, 2, 3], 2, &mut out);
        assert_eq!(out, vec![3, 2, 1, 2, 3, 2, 1]);
    }
}
