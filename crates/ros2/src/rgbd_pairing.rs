//! Live colour and depth images paired by their `header.stamp`s, online, to give the pairs the
//! bag reader's rule gives offline ([`slamkit_io::tum_rgbd::associate`]: the closest depth
//! image within [`MAX_PAIR_GAP_S`], each image used once).
//!
//! A colour image is decided once a depth image stamped at or after it has come: depth stamps
//! only grow (one driver per topic), so no later depth image can be closer. It then takes the
//! closest waiting depth image within the gap, and the depth images before that one are left
//! unpaired (a later colour image is farther from them still); with none within the gap the
//! colour image is left unpaired. A camera whose depth stream stops does not fill memory: past
//! [`MAX_WAITING`] colour images the oldest is decided with what has come. For a camera that
//! stamps both images of a frame alike (RealSense's aligned depth, Kinect's registered depth)
//! every frame pairs with its own depth image, as offline.

use slamkit_io::bag::rgbd::MAX_PAIR_GAP_S;
use std::collections::VecDeque;

/// Colour images kept waiting for their depth image at most.
pub const MAX_WAITING: usize = 30;

/// Pairs colour and depth images by stamp (see the module documentation).
///
/// ```
/// use slamkit_ros2::rgbd_pairing::RgbdPairing;
/// let mut pairing = RgbdPairing::new();
/// assert!(pairing.add_colour(1.00, "c1").is_empty());
/// assert!(pairing.add_colour(1.10, "c2").is_empty());
/// // a depth image 5 ms after c1 decides c1
/// assert_eq!(pairing.add_depth(1.005, "d1"), [("c1", "d1")]);
/// // c2's depth image was lost: the next one decides it, unpaired (80 ms away)
/// assert!(pairing.add_depth(1.18, "d3").is_empty());
/// assert_eq!(pairing.unpaired(), (1, 0));
/// ```
pub struct RgbdPairing<C, D> {
    colour: VecDeque<(f64, C)>,
    depth: VecDeque<(f64, D)>,
    unpaired_colour: usize,
    unpaired_depth: usize,
}

impl<C, D> Default for RgbdPairing<C, D> {
    fn default() -> Self {
        Self::new()
    }
}

impl<C, D> RgbdPairing<C, D> {
    /// Nothing waiting.
    pub fn new() -> Self {
        Self {
            colour: VecDeque::new(),
            depth: VecDeque::new(),
            unpaired_colour: 0,
            unpaired_depth: 0,
        }
    }

    /// Takes a colour image stamped `t` \[s\]; returns the pairs now decided, in order.
    pub fn add_colour(&mut self, t: f64, image: C) -> Vec<(C, D)> {
        self.colour.push_back((t, image));
        self.decide(false)
    }

    /// Takes a depth image stamped `t` \[s\]; returns the pairs now decided, in order.
    pub fn add_depth(&mut self, t: f64, image: D) -> Vec<(C, D)> {
        self.depth.push_back((t, image));
        self.decide(false)
    }

    /// Decides every waiting colour image with the depth images that came (the input ended).
    pub fn finish(&mut self) -> Vec<(C, D)> {
        let pairs = self.decide(true);
        self.unpaired_depth += self.depth.len();
        self.depth.clear();
        pairs
    }

    /// Colour and depth images left without a partner so far.
    pub fn unpaired(&self) -> (usize, usize) {
        (self.unpaired_colour, self.unpaired_depth)
    }

    fn decide(&mut self, all: bool) -> Vec<(C, D)> {
        let mut pairs = Vec::new();
        while let Some(&(tc, _)) = self.colour.front() {
            // depth images too old for this colour image are too old for every later one
            while self
                .depth
                .front()
                .is_some_and(|(td, _)| *td < tc - MAX_PAIR_GAP_S)
            {
                self.depth.pop_front();
                self.unpaired_depth += 1;
            }
            let decided = all
                || self.colour.len() > MAX_WAITING
                || self.depth.back().is_some_and(|(td, _)| *td >= tc);
            if !decided {
                break;
            }
            let Some((_, colour)) = self.colour.pop_front() else {
                break;
            };
            let closest = self
                .depth
                .iter()
                .enumerate()
                .map(|(i, (td, _))| (i, (td - tc).abs()))
                .filter(|(_, gap)| *gap <= MAX_PAIR_GAP_S)
                .min_by(|a, b| a.1.total_cmp(&b.1));
            match closest {
                Some((i, _)) => {
                    self.unpaired_depth += i;
                    let mut rest = self.depth.split_off(i);
                    self.depth.clear();
                    if let Some((_, depth)) = rest.pop_front() {
                        pairs.push((colour, depth));
                    }
                    self.depth = rest;
                }
                None => self.unpaired_colour += 1,
            }
        }
        pairs
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use slamkit_io::tum_rgbd::associate;

    /// On streams with jitter, lost images and depth arriving before or after its colour
    /// image, the online pairs are the offline rule's.
    #[test]
    fn online_pairs_are_the_offline_ones() {
        let colour: Vec<(f64, usize)> = (0..200)
            .filter(|i| i % 17 != 5)
            .map(|i| (f64::from(i) / 30.0 + 0.002 * f64::from(i % 3), i as usize))
            .collect();
        let depth: Vec<(f64, usize)> = (0..200)
            .filter(|i| i % 23 != 7)
            .map(|i| (f64::from(i) / 30.0 + 0.004 * f64::from(i % 4), i as usize))
            .collect();
        let offline: Vec<(usize, usize)> = associate(&colour, &depth, MAX_PAIR_GAP_S)
            .into_iter()
            .map(|(c, d)| (c.1, d.1))
            .collect();
        for depth_lag in [0, 3] {
            let mut pairing = RgbdPairing::new();
            let mut online = Vec::new();
            // depth images come `depth_lag` frames late
            for i in 0..colour.len().max(depth.len()) + depth_lag {
                if let Some(&(t, c)) = colour.get(i) {
                    online.extend(pairing.add_colour(t, c));
                }
                if let Some(&(t, d)) = i.checked_sub(depth_lag).and_then(|j| depth.get(j)) {
                    online.extend(pairing.add_depth(t, d));
                }
            }
            online.extend(pairing.finish());
            assert_eq!(online, offline, "depth {depth_lag} frames late");
            let (uc, ud) = pairing.unpaired();
            assert_eq!(uc + online.len(), colour.len());
            assert_eq!(ud + online.len(), depth.len());
        }
    }

    #[test]
    fn a_stopped_depth_stream_does_not_hold_colour_forever() {
        let mut pairing = RgbdPairing::<usize, usize>::new();
        for i in 0..MAX_WAITING + 5 {
            assert!(pairing.add_colour(i as f64, i).is_empty());
        }
        assert_eq!(pairing.unpaired(), (5, 0));
    }
}
