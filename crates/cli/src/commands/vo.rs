//! `slamkit vo`: visual odometry on an RGB-D or stereo dataset folder, through the
//! [`VisualSlam`] session (started at the identity), with the trajectory, ground truth, point
//! cloud and report written to the output folder, the maps to plan in built from the keyframes
//! (`octree.bt` and the floor grid `floor.pgm/.yaml/.png` for RGB-D), and
//! with `--save-map` the keyframes as a `.skmap` file.

use crate::output::{finish_with_page, merge_json, progress_bar};
use anyhow::Context;
use serde_json::json;
use slamkit_core::Observation;
use slamkit_io::bag::RgbdTopics;
use slamkit_io::output_folder::OutputFolder;
use slamkit_io::IoError;
use slamkit_io::{Dataset, DatasetFormat as IoFormat};
use slamkit_slam::profile::layout_profile;
use slamkit_slam::record::VisualRecording;
use slamkit_slam::visual::planning_map::PlanningMapConfig;
use slamkit_slam::visual::run_files::{self, DatasetRun};
use slamkit_slam::visual::{self, PointMapping, RunOptions, VisualSlam};
use slamkit_slam::Session;
use slamkit_vo::{FrontendKind, VoConfig};
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The files `slamkit vo` writes in `--out`.
const OUTPUTS: &[&str] = &[
    "trajectory.tum",
    "trajectory.kitti",
    "groundtruth.tum",
    "cloud.ply",
    "octree.bt",
    "floor.pgm",
    "floor.yaml",
    "floor.png",
    "report.json",
    "report.html",
];

/// Dataset folder layouts `slamkit vo` reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum DatasetFormat {
    /// TUM RGB-D: rgb.txt, depth.txt, groundtruth.txt.
    Tum,
    /// KITTI odometry stereo: image_0/, image_1/, calib.txt, poses.txt.
    Kitti,
    /// Microsoft 7-Scenes: frame-NNNNNN.color/depth/pose.
    #[value(name = "7scenes")]
    SevenScenes,
    /// Open3D / Redwood RGB-D: color/, depth/, trajectory.log.
    Redwood,
    /// EuRoC MAV: cam0/, cam1/.
    Euroc,
}

/// Feature front ends.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum Frontend {
    /// Shi–Tomasi corners tracked with pyramidal KLT.
    Klt,
    /// ORB features matched by Hamming distance.
    Orb,
}

/// Arguments of `slamkit vo`.
#[derive(Debug, clap::Args)]
pub struct VoArgs {
    /// Dataset folder, or a ROS 1 / ROS 2 bag of an RGB-D camera.
    pub dataset_dir: PathBuf,
    /// The bag's topics, when the input is a bag.
    #[command(flatten)]
    pub topics: CameraTopicArgs,
    /// Folder layout; told from the folder's content when omitted.
    #[arg(long)]
    pub format: Option<DatasetFormat>,
    /// Feature front end.
    #[arg(long, value_enum, default_value = "klt")]
    pub frontend: Frontend,
    /// Named profile of the camera (`stereo`, `kinect-v1`; or a profile file `X.toml`):
    /// its `[vo]` settings. Default: the layout's camera (`stereo` for kitti and euroc,
    /// `kinect-v1` for 7scenes, none for tum and redwood).
    #[arg(long)]
    pub profile: Option<String>,
    /// TOML file with settings laid over the profile's (the fields report.json shows under
    /// `config`; see the README's configuration section).
    #[arg(long)]
    pub config: Option<PathBuf>,
    /// Visual SLAM: keyframes, place recognition and loop closure over the odometry (the
    /// `[vo.loop_closure]` settings, on).
    #[arg(long)]
    pub slam: bool,
    /// Play the dataset at its frame rate and drop the frames the pipeline cannot take.
    #[arg(long)]
    pub realtime: bool,
    /// Write the map (keyframe poses, their 3D points and ORB descriptors) to this `.skmap`.
    #[arg(long)]
    pub save_map: Option<PathBuf>,
    /// Localise in this saved map (a `.skmap` of a `--slam` run with the same kind of camera)
    /// instead of building one: no start pose, poses in the map's frame, the map unchanged.
    #[arg(long, conflicts_with_all = ["save_map", "slam"])]
    pub localize: Option<PathBuf>,
    /// Record the run to this MCAP file (Foxglove's JSON schemas, for Foxglove): each
    /// frame's image (JPEG), its pose and `map → camera`, the path ten times over the run, and
    /// at the end the final path and the point map.
    #[arg(long, value_name = "FILE.mcap")]
    pub record: Option<PathBuf>,
    /// Output folder.
    #[arg(long, default_value = "out/vo")]
    pub out: PathBuf,
}

/// The camera topics of a bag (chosen by type and encoding when there is one of each).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct CameraTopicArgs {
    /// Topic of the colour images (`sensor_msgs/Image`: rgb8, bgr8, mono8) in a bag.
    #[arg(long)]
    pub rgb_topic: Option<String>,
    /// Topic of the depth images registered to colour (16UC1 mm, 32FC1 m) in a bag.
    #[arg(long)]
    pub depth_topic: Option<String>,
    /// Topic of the colour camera's `sensor_msgs/CameraInfo` in a bag.
    #[arg(long)]
    pub camera_info_topic: Option<String>,
}

/// Runs `slamkit vo`.
pub fn run(args: &VoArgs) -> anyhow::Result<()> {
    let started = Instant::now();
    let format = match args.format {
        Some(f) => io_format(f),
        None => detect_format(&args.dataset_dir)?,
    };
    let config = load_config(args, format)?;
    let folder = OutputFolder::create(&args.out, OUTPUTS)?;
    let out = folder.path();
    if let Some(parent) = args.save_map.as_deref().and_then(Path::parent) {
        let parent = if parent.as_os_str().is_empty() {
            Path::new(".")
        } else {
            parent
        };
        anyhow::ensure!(
            parent.is_dir(),
            "--save-map: the folder {} does not exist",
            parent.display()
        );
    }
    let t = &args.topics;
    let topics = RgbdTopics {
        rgb: t.rgb_topic.clone(),
        depth: t.depth_topic.clone(),
        camera_info: t.camera_info_topic.clone(),
    };
    anyhow::ensure!(
        format == IoFormat::RosBag || topics == RgbdTopics::default(),
        "the topic options apply to bags; {} is not one",
        args.dataset_dir.display()
    );
    let dataset = match format {
        IoFormat::RosBag => Dataset::open_bag(&args.dataset_dir, &topics),
        _ => Dataset::open(&args.dataset_dir, format),
    };
    let dataset = dataset.with_context(|| format!("opening {}", args.dataset_dir.display()))?;
    if let Dataset::RgbdBag(bag) = &dataset {
        println!("bag {}: {}", args.dataset_dir.display(), bag.describe());
    }
    anyhow::ensure!(
        !dataset.is_empty(),
        "{} holds no frame",
        args.dataset_dir.display()
    );
    let bar = progress_bar(dataset.len() as u64, "vo");
    let options = RunOptions {
        realtime: args.realtime,
    };
    let mapping = if args.realtime {
        PointMapping::WhenIdle
    } else {
        PointMapping::EveryFrame
    };
    let rig = visual::rig_of(&dataset);
    let session = match &args.localize {
        Some(path) => {
            VisualSlam::localising_in(&config, rig.clone(), &visual::load_map(path, &rig)?)?
        }
        None => VisualSlam::new(&config, rig)?,
    };
    let mut session = session.with_point_map(mapping)?;
    let mut recording = match &args.record {
        Some(path) => Some(VisualRecording::create(path, dataset.len())?),
        None => None,
    };
    let source: Box<dyn Iterator<Item = Result<Observation, IoError>> + Send + '_> =
        match &recording {
            Some(r) => Box::new(r.tap(dataset.observations())),
            None => dataset.observations(),
        };
    let mut recording_error = None;
    let result = visual::run(&mut session, source, options, |update| {
        bar.inc(1);
        if let Some(Err(e)) = recording.as_mut().map(|r| r.push(update)) {
            recording_error.get_or_insert(e);
        }
    })?;
    bar.finish_and_clear();
    if let Some(e) = recording_error {
        return Err(e.into());
    }
    for line in &result.skipped {
        eprintln!("skipped {line}");
    }
    if let Some(path) = &args.save_map {
        Session::save(&session, path)?;
    }
    let run = DatasetRun::finish(session, result)?;
    let recorded = match recording {
        Some(r) => {
            let cloud = run.output.point_map.as_ref().map(|m| m.to_cloud());
            Some(r.finish(&run.run.trajectory, cloud.as_ref())?)
        }
        None => None,
    };
    let (mut report, metrics) = run.write(out, &dataset, format, &PlanningMapConfig::default())?;
    merge_json(
        &mut report,
        json!({
            "input": args.dataset_dir,
            "format": format!("{format:?}"),
            "realtime": args.realtime,
            "profile": args.profile.as_deref().or_else(|| layout_profile(format)),
            "config": config,
            "wall_seconds": started.elapsed().as_secs_f64(),
            "recording": recorded.map(|messages| json!({ "file": args.record, "messages": messages })),
        }),
    );
    report["map"]["saved_to"] = json!(args.save_map);
    report["map"]["localised_in"] = json!(args.localize);
    let name = args
        .dataset_dir
        .file_name()
        .unwrap_or(args.dataset_dir.as_os_str());
    finish_with_page(
        folder,
        &report,
        &format!("slamkit vo: {}", name.to_string_lossy()),
    )?;
    println!("{}", run_files::summary(&report));
    if let Some(metrics) = &metrics {
        println!("{metrics}");
    }
    println!("outputs in {}", args.out.display());
    Ok(())
}

fn io_format(f: DatasetFormat) -> IoFormat {
    match f {
        DatasetFormat::Tum => IoFormat::Tum,
        DatasetFormat::Kitti => IoFormat::Kitti,
        DatasetFormat::SevenScenes => IoFormat::SevenScenes,
        DatasetFormat::Redwood => IoFormat::Redwood,
        DatasetFormat::Euroc => IoFormat::Euroc,
    }
}

/// Tells the layout from the folder's content.
fn detect_format(dir: &Path) -> anyhow::Result<IoFormat> {
    let detected = slamkit_io::layout::detect_layout(dir)?;
    detected.with_context(|| format!("cannot tell the layout of {}: pass --format", dir.display()))
}

/// The session's settings ([`visual::session_settings`]) for the chosen front end.
fn load_config(args: &VoArgs, format: IoFormat) -> anyhow::Result<VoConfig> {
    let frontend = frontend_kind(args.frontend);
    let profile = args.profile.as_deref();
    let config = args.config.as_deref();
    Ok(visual::session_settings(
        frontend, format, profile, config, args.slam,
    )?)
}

/// The session's front end for the command-line choice.
pub fn frontend_kind(frontend: Frontend) -> FrontendKind {
    match frontend {
        Frontend::Klt => FrontendKind::Klt,
        Frontend::Orb => FrontendKind::Orb,
    }
}
