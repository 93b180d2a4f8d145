//! The world point map of a visual session ([`VoxelMap`]: every 4th depth pixel of RGB-D
//! frames, the features with depth of stereo frames), filled on its own thread so that merging
//! points into the voxel hash (3–4 ms a frame on 7-Scenes, more while the table grows) never
//! holds tracking back.

use std::thread::JoinHandle;

use crossbeam_channel::{bounded, Sender, TrySendError};
use slamkit_core::{Pose3, StageTimings};
use slamkit_vo::frame::MapSource;
use slamkit_vo::voxel_map::VoxelMapConfig;
use slamkit_vo::VoxelMap;

use crate::SlamError;

/// Frames the mapping thread may have waiting.
const QUEUE: usize = 4; // documented on PointMapping::EveryFrame

/// How the session builds its world point map.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum PointMapping {
    /// No point map (a robot that maps otherwise, e.g. into a floor grid).
    Off,
    /// Every tracked frame's points enter the map; tracking waits when the mapping thread is
    /// four frames behind.
    #[default]
    EveryFrame,
    /// Live cameras: a frame whose points arrive while the mapping thread is busy is left out
    /// of the map (counted), so mapping never delays tracking.
    WhenIdle,
}

/// A frame's points at the pose they were seen from.
struct Placed {
    world_from_camera: Pose3,
    source: MapSource,
}

/// The mapping thread's end of the session.
pub(super) struct PointMapper {
    sender: Option<Sender<Placed>>,
    worker: Option<JoinHandle<(VoxelMap, StageTimings)>>,
    wait: bool,
    unmapped: usize,
}

impl PointMapper {
    /// Starts the mapping thread (none for [`PointMapping::Off`]).
    pub(super) fn start(mode: PointMapping, config: VoxelMapConfig) -> Result<Self, SlamError> {
        let mut mapper = Self {
            sender: None,
            worker: None,
            wait: mode == PointMapping::EveryFrame,
            unmapped: 0,
        };
        if mode == PointMapping::Off {
            return Ok(mapper);
        }
        let (sender, receiver) = bounded::<Placed>(QUEUE);
        let worker = std::thread::Builder::new()
            .name("vo-point-map".into())
            .spawn(move || {
                let mut map = VoxelMap::new(config);
                let mut timings = StageTimings::default();
                for placed in receiver {
                    timings.time("map", || {
                        let (points, colors) = placed.source.points();
                        map.insert(&placed.world_from_camera, &points, &colors);
                    });
                }
                (map, timings)
            })
            .map_err(|e| SlamError::Thread(e.to_string()))?;
        mapper.sender = Some(sender);
        mapper.worker = Some(worker);
        Ok(mapper)
    }

    /// Hands a tracked frame's points (camera frame) to the mapping thread.
    pub(super) fn insert(&mut self, world_from_camera: Pose3, source: MapSource) {
        let Some(sender) = &self.sender else {
            return;
        };
        let placed = Placed {
            world_from_camera,
            source,
        };
        let delivered = if self.wait {
            sender.send(placed).is_ok()
        } else {
            match sender.try_send(placed) {
                Ok(()) => true,
                Err(TrySendError::Full(_)) => {
                    self.unmapped += 1;
                    true
                }
                Err(TrySendError::Disconnected(_)) => false,
            }
        };
        if !delivered {
            // the thread is gone (it panicked): no map from here on
            self.sender = None;
        }
    }

    /// Frames left out of the map because the mapping thread was busy.
    pub(super) fn unmapped(&self) -> usize {
        self.unmapped
    }

    /// Waits for the mapping thread to insert everything sent; the map and its timings
    /// (`None` with [`PointMapping::Off`]).
    pub(super) fn finish(mut self) -> Result<Option<(VoxelMap, StageTimings)>, SlamError> {
        self.sender = None;
        match self.worker.take() {
            None => Ok(None),
            Some(worker) => worker
                .join()
                .map(Some)
                .map_err(|_| SlamError::Thread("the point-map thread panicked".into())),
        }
    }
}

impl std::fmt::Debug for PointMapper {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("PointMapper")
            .field("running", &self.worker.is_some())
            .field("wait", &self.wait)
            .field("unmapped", &self.unmapped)
            .finish()
    }
}
