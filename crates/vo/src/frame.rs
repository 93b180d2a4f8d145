//! The first half of a frame's work: a decoded frame becomes a [`PreparedFrame`] — grey image (CLAHE
//! on CIELAB L for colour input when configured), darkness check, the depth source (registered
//! depth image or the right image), the KLT pyramid or ORB features, and the detected features
//! lifted to 3D.

use std::sync::Arc;

use nalgebra::{Point2, Point3};
use slamkit_core::camera::Intrinsics;
use slamkit_core::image::{GrayImage, Image, RgbImage};
use slamkit_vision::color::{rgb_to_gray, rgb_to_lab_planes};
use slamkit_vision::{shi_tomasi, Clahe, Descriptor, KltPyramid, Orb, StereoPair};

use crate::config::{FrontendKind, VoConfig};
use crate::covisibility::PlaceFeatures;
use crate::depth::{depth_at, lift, DepthConfig};
use crate::error::VoError;
use crate::motion::StereoCamera;
use crate::registration::RegisteredDepth;
use crate::FailReason;

/// Camera-frame points and their RGB colours, index-aligned.
pub type ColoredPoints = (Vec<Point3<f64>>, Vec<[u8; 3]>);

/// The decoded images of one frame.
#[derive(Debug, Clone)]
pub enum SensorImages {
    /// Colour and depth \[m\] (0 = no depth), depth in the depth camera.
    Rgbd {
        /// Colour image.
        color: RgbImage,
        /// Depth image \[m\].
        depth_m: Image<f32>,
    },
    /// A rectified stereo pair.
    Stereo {
        /// Left image (the tracked one).
        left: GrayImage,
        /// Right image.
        right: GrayImage,
    },
}

/// The camera rig: what the tracked image's pixels mean and where depth comes from.
#[derive(Debug, Clone, PartialEq)]
pub enum Rig {
    /// An RGB-D camera.
    Rgbd {
        /// Intrinsics of the colour camera as given by the dataset.
        color: Intrinsics,
        /// Intrinsics of the depth camera.
        depth: Intrinsics,
    },
    /// A rectified stereo camera.
    Stereo {
        /// Intrinsics of the left camera.
        left: Intrinsics,
        /// Distance between the optical centres \[m\].
        baseline_m: f64,
    },
}

/// Where the 3D position of a pixel of the tracked image comes from.
#[derive(Debug, Clone)]
enum DepthSource {
    /// A depth image, shared with the map stage.
    Image(DepthImage),
    /// A rectified pair, prepared once for all the points matched in it.
    Right(Box<StereoPair>),
}

/// The depth image of an RGB-D frame.
#[derive(Debug, Clone)]
enum DepthImage {
    /// Depth \[m\] registered to the tracked image.
    InColorCamera(Arc<Image<f32>>),
    /// Depth \[m\] of an unregistered depth camera, read in the tracked (colour) image.
    Warped(Arc<RegisteredDepth>),
}

/// What a frame adds to the world point map. Turning a depth image into points is the mapping
/// stage's work ([`MapSource::points`], in the map thread), not the frame's preparation.
#[derive(Debug, Clone, Default)]
pub struct MapSource(MapInput);

#[derive(Debug, Clone, Default)]
enum MapInput {
    #[default]
    Nothing,
    /// Points already known: the features with depth (stereo).
    Points(ColoredPoints),
    /// Every 4th pixel of a depth image with its colour.
    Depth {
        depth: DepthImage,
        color: RgbImage,
        camera: Intrinsics,
        config: DepthConfig,
    },
}

impl MapSource {
    /// Camera-frame points (tracked camera) and their colours: every 4th depth pixel within the
    /// configured depth range with its colour (RGB-D; for an unregistered pair the depth
    /// camera's pixels moved into the colour camera), the features with depth (stereo, grey).
    pub fn points(&self) -> ColoredPoints {
        match &self.0 {
            MapInput::Nothing => (Vec::new(), Vec::new()),
            MapInput::Points(points) => points.clone(),
            MapInput::Depth {
                depth: DepthImage::Warped(depth),
                color,
                config,
                ..
            } => depth.samples(4, color, config),
            MapInput::Depth {
                depth: DepthImage::InColorCamera(depth),
                color,
                camera,
                config,
            } => {
                let mut out = (Vec::new(), Vec::new());
                for y in (0..depth.height()).step_by(4) {
                    for x in (0..depth.width()).step_by(4) {
                        let (Some(&z), Some(&c)) = (depth.get(x, y), color.get(x, y)) else {
                            continue;
                        };
                        let z = f64::from(z);
                        if z >= config.min_depth_m && z <= config.max_depth_m {
                            out.0.push(lift(camera, Point2::new(x as f64, y as f64), z));
                            out.1.push(c);
                        }
                    }
                }
                out
            }
        }
    }
}

/// Detected features of a frame.
#[derive(Debug, Clone, Default)]
pub struct Features {
    /// Pixel positions in the tracked image.
    pub pixels: Vec<Point2<f64>>,
    /// Camera-frame positions \[m\]; `None` without depth. Empty when lifted on demand: the
    /// KLT corners of an RGB-D frame, most of which never join the reference (the tracker
    /// lifts those that do with [`PreparedFrame::lift`]).
    pub points: Vec<Option<Point3<f64>>>,
    /// ORB descriptors (empty for the KLT front end).
    pub descriptors: Vec<Descriptor>,
}

/// A frame ready for motion estimation.
#[derive(Debug, Clone)]
pub struct PreparedFrame {
    /// Position in the sequence.
    pub index: usize,
    /// Time stamp \[s\].
    pub timestamp: f64,
    /// Intrinsics of the tracked image.
    pub camera: Intrinsics,
    /// The KLT pyramid (KLT front end).
    pub pyramid: Option<KltPyramid>,
    /// Whether the grey image (and so `pyramid` and the features) went through CLAHE.
    pub clahe: bool,
    /// The KLT pyramid of the other grey image (plain when `clahe`, CLAHE's otherwise) on a
    /// frame where automatic CLAHE switched (`auto_clahe`): the reference, prepared before
    /// the switch, is tracked into this one, whose grey levels match its own, and the next
    /// frame is tracked from `pyramid`. `None` on every other frame.
    pub bridge: Option<KltPyramid>,
    /// Detected features.
    pub features: Features,
    /// What the frame adds to the world map.
    pub map_source: MapSource,
    /// ORB features with depth for place recognition (`loop_closure.enabled` only): the ORB
    /// front end's own, or those of `loop_closure.orb` for the KLT front end.
    pub place: Option<PlaceFeatures>,
    gray: GrayImage,
    depth: DepthSource,
    baseline_m: f64,
}

/// Turns decoded frames into [`PreparedFrame`]s; holds the reusable kernels.
#[derive(Debug)]
pub struct Preprocessor {
    config: VoConfig,
    rig: Rig,
    clahe: Option<Clahe>,
    orb: Option<Orb>,
    /// ORB for place recognition beside the KLT front end.
    place_orb: Option<Orb>,
    /// Automatic CLAHE's state (`auto_clahe`).
    auto: AutoState,
}

/// Whether automatic CLAHE is on, and the frames since the plain image was last detected on.
#[derive(Debug, Default)]
struct AutoState {
    on: bool,
    since_check: usize,
}

/// Pixels and (ORB) descriptors detected in one grey image.
type Detected = (Vec<Point2<f64>>, Vec<Descriptor>);

impl Preprocessor {
    /// Builds the kernels of `config` for `rig`.
    ///
    /// # Errors
    /// [`VoError`] for an invalid configuration.
    pub fn new(config: &VoConfig, rig: Rig) -> Result<Self, VoError> {
        config.validate()?;
        let clahe = (config.use_clahe || config.auto_clahe.enabled())
            .then(|| Clahe::new(config.clahe.clone()))
            .transpose()?;
        let orb = (config.frontend == FrontendKind::Orb)
            .then(|| Orb::new(config.orb.clone()))
            .transpose()?;
        let place_orb = (config.loop_closure.enabled && config.frontend == FrontendKind::Klt)
            .then(|| Orb::new(config.loop_closure.orb.clone()))
            .transpose()?;
        Ok(Self {
            config: config.clone(),
            rig,
            clahe,
            orb,
            place_orb,
            auto: AutoState::default(),
        })
    }

    /// Intrinsics of the tracked image (the colour camera after registration).
    pub fn camera(&self) -> Intrinsics {
        match (&self.rig, &self.config.register_depth) {
            (Rig::Rgbd { color, .. }, Some(reg)) => reg.color_camera(color.width, color.height),
            (Rig::Rgbd { color, .. }, None) => *color,
            (Rig::Stereo { left, .. }, _) => *left,
        }
    }

    /// Prepares one frame.
    ///
    /// # Errors
    /// A [`FailReason`] for a frame that cannot be tracked (too dark, image sizes that do not
    /// fit, no depth at all).
    pub fn prepare(
        &mut self,
        index: usize,
        timestamp: f64,
        images: SensorImages,
    ) -> Result<PreparedFrame, FailReason> {
        let camera = self.camera();
        let (plain, depth, colors) = match images {
            SensorImages::Rgbd { color, depth_m } => {
                if (color.width(), color.height()) != (depth_m.width(), depth_m.height()) {
                    return Err(FailReason::SizeMismatch);
                }
                let depth = match (&self.rig, &self.config.register_depth) {
                    (Rig::Rgbd { depth: k, .. }, Some(reg)) => {
                        DepthImage::Warped(Arc::new(RegisteredDepth::new(depth_m, k, reg)))
                    }
                    _ => DepthImage::InColorCamera(Arc::new(depth_m)),
                };
                (rgb_to_gray(&color), DepthSource::Image(depth), Some(color))
            }
            SensorImages::Stereo { left, right } => {
                if (left.width(), left.height()) != (right.width(), right.height()) {
                    return Err(FailReason::SizeMismatch);
                }
                // the pair stays plain: depth is matched between two images of one kind,
                // whatever the tracked image went through
                let pair =
                    StereoPair::new(left.clone(), right).map_err(|_| FailReason::SizeMismatch)?;
                (left, DepthSource::Right(Box::new(pair)), None)
            }
        };
        if (plain.width(), plain.height()) != (camera.width, camera.height) {
            return Err(FailReason::SizeMismatch);
        }
        // the scene's light, before any contrast enhancement
        // (an integer sum: vectorised; exact, as was the f64 sum of integers below 2^53)
        let sum: u64 = plain.data().iter().map(|&v| u64::from(v)).sum();
        let mean = sum as f64 / plain.data().len().max(1) as f64;
        if mean < self.config.min_mean_intensity {
            return Err(FailReason::TooDark { mean_grey: mean });
        }
        let (gray, clahe, (pixels, descriptors), other) =
            self.choose_image(plain, colors.as_ref())?;
        let baseline_m = match self.rig {
            Rig::Stereo { baseline_m, .. } => baseline_m,
            Rig::Rgbd { .. } => 0.0,
        };
        let mut frame = PreparedFrame {
            index,
            timestamp,
            camera,
            pyramid: None,
            clahe,
            bridge: None,
            features: Features::default(),
            map_source: MapSource::default(),
            place: None,
            gray,
            depth,
            baseline_m,
        };
        if self.orb.is_none() {
            let level = self.config.klt.max_level;
            frame.pyramid = Some(KltPyramid::new(&frame.gray, level));
            frame.bridge = other.map(|g| KltPyramid::new(&g, level));
        }
        let points = match (&frame.depth, &self.orb) {
            (DepthSource::Image(_), None) => Vec::new(),
            _ => frame.lift(&pixels, &self.config)?,
        };
        frame.features = Features {
            pixels,
            points,
            descriptors,
        };
        if self.config.loop_closure.enabled {
            frame.place = Some(self.place_features(&frame)?);
        }
        frame.map_source = MapSource(match (&frame.depth, colors) {
            (DepthSource::Image(depth), Some(color)) => MapInput::Depth {
                depth: depth.clone(),
                color,
                camera,
                config: self.config.depth.clone(),
            },
            _ => MapInput::Points(frame.feature_points()),
        });
        Ok(frame)
    }

    /// The grey image features are detected and tracked in, whether it went through CLAHE,
    /// its detections, and on a frame where automatic CLAHE switched the other grey image
    /// (see [`PreparedFrame::bridge`]). CLAHE works on CIELAB L for colour input.
    fn choose_image(
        &mut self,
        plain: GrayImage,
        color: Option<&RgbImage>,
    ) -> Result<(GrayImage, bool, Detected, Option<GrayImage>), FailReason> {
        let Some(kernel) = &mut self.clahe else {
            let found = detect(self.orb.as_ref(), &self.config, &plain)?;
            return Ok((plain, false, found, None));
        };
        let mut enhance = || match color {
            Some(c) => kernel.apply_gray(&rgb_to_lab_planes(c).0),
            None => kernel.apply_gray(&plain),
        };
        if self.config.use_clahe {
            let gray = enhance();
            let found = detect(self.orb.as_ref(), &self.config, &gray)?;
            return Ok((gray, true, found, None));
        }
        let auto = &self.config.auto_clahe;
        if self.auto.on {
            let enhanced = enhance();
            self.auto.since_check += 1;
            if self.auto.since_check >= auto.recheck_every {
                self.auto.since_check = 0;
                let found = detect(self.orb.as_ref(), &self.config, &plain)?;
                if found.0.len() >= auto.off_at {
                    self.auto.on = false;
                    return Ok((plain, false, found, Some(enhanced)));
                }
            }
            let found = detect(self.orb.as_ref(), &self.config, &enhanced)?;
            return Ok((enhanced, true, found, None));
        }
        let found = detect(self.orb.as_ref(), &self.config, &plain)?;
        if found.0.len() >= auto.on_below {
            return Ok((plain, false, found, None));
        }
        let enhanced = enhance();
        self.auto = AutoState {
            on: true,
            since_check: 0,
        };
        let found = detect(self.orb.as_ref(), &self.config, &enhanced)?;
        Ok((enhanced, true, found, Some(plain)))
    }

    /// The frame's ORB features with depth: the front end's, or ORB's beside KLT.
    fn place_features(&self, frame: &PreparedFrame) -> Result<PlaceFeatures, FailReason> {
        let (points, descriptors) = match &self.place_orb {
            Some(orb) => {
                let f = orb.detect_and_compute(&frame.gray);
                let pixels: Vec<Point2<f64>> = f
                    .keypoints
                    .iter()
                    .map(|k| Point2::new(f64::from(k.x), f64::from(k.y)))
                    .collect();
                (frame.lift(&pixels, &self.config)?, f.descriptors)
            }
            None => (
                frame.features.points.clone(),
                frame.features.descriptors.clone(),
            ),
        };
        Ok(points
            .into_iter()
            .zip(descriptors)
            .filter_map(|(p, d)| Some((p?, d)))
            .fold(PlaceFeatures::default(), |mut acc, (p, d)| {
                acc.points.push(p);
                acc.descriptors.push(d);
                acc
            }))
    }
}

/// ORB features (`orb` given) or Shi–Tomasi corners of `gray`.
fn detect(orb: Option<&Orb>, config: &VoConfig, gray: &GrayImage) -> Result<Detected, FailReason> {
    Ok(match orb {
        Some(orb) => {
            let f = orb.detect_and_compute(gray);
            let px = f
                .keypoints
                .iter()
                .map(|k| Point2::new(f64::from(k.x), f64::from(k.y)))
                .collect();
            (px, f.descriptors)
        }
        None => {
            let corners = shi_tomasi(gray, &config.shi_tomasi)
                .map_err(|e| FailReason::Kernel(e.to_string()))?;
            let px = corners
                .iter()
                .map(|c| Point2::new(f64::from(c.x), f64::from(c.y)))
                .collect();
            (px, Vec::new())
        }
    })
}

impl PreparedFrame {
    /// The camera for motion estimation: the stereo baseline, or the configured virtual
    /// baseline of an RGB-D depth sensor.
    pub fn stereo_camera(&self, config: &VoConfig) -> StereoCamera {
        let baseline = match self.depth {
            DepthSource::Right(_) => self.baseline_m,
            DepthSource::Image(_) => config.depth.virtual_baseline_m,
        };
        StereoCamera {
            k: self.camera,
            bf: self.camera.fx * baseline,
        }
    }

    /// The grey image features are tracked in.
    pub fn gray(&self) -> &GrayImage {
        &self.gray
    }

    /// The 3D points (camera frame) of `pixels`, from depth or stereo; `None` where unknown.
    ///
    /// # Errors
    /// [`FailReason::Kernel`] when the stereo matcher rejects its configuration.
    pub fn lift(
        &self,
        pixels: &[Point2<f64>],
        config: &VoConfig,
    ) -> Result<Vec<Option<Point3<f64>>>, FailReason> {
        let k = &self.camera;
        match &self.depth {
            DepthSource::Image(DepthImage::InColorCamera(depth)) => Ok(pixels
                .iter()
                .map(|&px| depth_at(depth, px, &config.depth).map(|z| lift(k, px, z)))
                .collect()),
            DepthSource::Image(DepthImage::Warped(depth)) => Ok(pixels
                .iter()
                .map(|&px| depth.depth_at(px, &config.depth).map(|z| lift(k, px, z)))
                .collect()),
            DepthSource::Right(pair) => {
                let pts: Vec<(f32, f32)> =
                    pixels.iter().map(|p| (p.x as f32, p.y as f32)).collect();
                let matches = pair
                    .match_points(&pts, &config.stereo)
                    .map_err(|e| FailReason::Kernel(e.to_string()))?;
                Ok(pixels
                    .iter()
                    .zip(matches)
                    .map(|(&px, m)| {
                        let z = k.fx * self.baseline_m / f64::from(m?.disparity_px);
                        (z > 0.0 && z <= config.max_stereo_depth_m).then(|| lift(k, px, z))
                    })
                    .collect())
            }
        }
    }

    /// The features with depth and their grey levels (the map points of a stereo frame).
    fn feature_points(&self) -> ColoredPoints {
        let f = &self.features;
        f.points
            .iter()
            .zip(&f.pixels)
            .filter_map(|(p, px)| {
                let g = *self
                    .gray
                    .get(px.x.round() as usize, px.y.round() as usize)?;
                p.map(|p| (p, [g; 3]))
            })
            .unzip()
    }
}
