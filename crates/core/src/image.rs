//! A minimal owned image: a row-major pixel buffer with its size, shared by the dataset readers
//! (slamkit-io) and the vision crates so neither depends on the other's image type.
//!
//! Pixel (x, y) has column x (rightwards) and row y (downwards), as in the camera frame's image
//! plane; it lives at `data[y * width + x]`.

/// An image of `width × height` pixels of type `T`, stored row by row.
///
/// The buffer always holds exactly `width * height` pixels; constructors check it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image<T> {
    width: usize,
    height: usize,
    data: Vec<T>,
}

/// 8-bit grayscale image.
pub type GrayImage = Image<u8>;
/// 8-bit RGB image, channels in the order red, green, blue.
pub type RgbImage = Image<[u8; 3]>;
/// Raw 16-bit depth image, in the dataset's own unit (see its depth scale).
pub type DepthImage = Image<u16>;

impl<T> Image<T> {
    /// Wraps a row-major buffer; `None` when `data.len() != width * height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Option<Self> {
        (width.checked_mul(height) == Some(data.len())).then_some(Self {
            width,
            height,
            data,
        })
    }

    /// Width \[px\].
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height \[px\].
    pub fn height(&self) -> usize {
        self.height
    }

    /// The pixel at column `x`, row `y`; `None` outside the image.
    pub fn get(&self, x: usize, y: usize) -> Option<&T> {
        if x < self.width && y < self.height {
            self.data.get(y * self.width + x)
        } else {
            None
        }
    }

    /// Mutable access to the pixel at column `x`, row `y`; `None` outside the image.
    pub fn get_mut(&mut self, x: usize, y: usize) -> Option<&mut T> {
        if x < self.width && y < self.height {
            self.data.get_mut(y * self.width + x)
        } else {
            None
        }
    }

    /// Row `y` as a slice of `width` pixels; `None` below the image.
    pub fn row(&self, y: usize) -> Option<&[T]> {
        if y < self.height {
            self.data.get(y * self.width..(y + 1) * self.width)
        } else {
            None
        }
    }

    /// All pixels, row-major.
    pub fn data(&self) -> &[T] {
        &self.data
    }

    /// All pixels, row-major, mutable (the size cannot change).
    pub fn data_mut(&mut self) -> &mut [T] {
        &mut self.data
    }

    /// Gives the buffer back, row-major.
    pub fn into_vec(self) -> Vec<T> {
        self.data
    }

    /// Applies `f` to every pixel, keeping the size.
    pub fn map<U>(&self, f: impl FnMut(&T) -> U) -> Image<U> {
        Image {
            width: self.width,
            height: self.height,
            data: self.data.iter().map(f).collect(),
        }
    }
}

impl<T: Clone> Image<T> {
    /// An image with every pixel set to `value`.
    pub fn filled(width: usize, height: usize, value: T) -> Self {
        Self {
            width,
            height,
            data: vec![value; width * height],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn indexing_is_row_major_and_bounded() {
        let img = Image::from_vec(3, 2, vec![0u8, 1, 2, 3, 4, 5]).unwrap();
        assert_eq!(img.get(2, 0), Some(&2));
        assert_eq!(img.get(0, 1), Some(&3));
        assert_eq!(img.get(3, 0), None);
        assert_eq!(img.get(0, 2), None);
        assert_eq!(img.row(1), Some(&[3u8, 4, 5][..]));
        assert_eq!(img.row(2), None);
    }

    #[test]
    fn size_mismatch_is_refused() {
        assert!(Image::from_vec(3, 2, vec![0u8; 5]).is_none());
        assert!(Image::from_vec(usize::MAX, 2, vec![0u8; 5]).is_none());
    }

    #[test]
    fn map_and_mutation_keep_size() {
        let mut img = Image::filled(2, 2, 10u16);
        *img.get_mut(1, 1).unwrap() = 20;
        let m = img.map(|&v| f64::from(v) / 10.0);
        assert_eq!(m.data(), &[1.0, 1.0, 1.0, 2.0]);
        assert_eq!((m.width(), m.height()), (2, 2));
    }
}
