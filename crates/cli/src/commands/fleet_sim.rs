//! `slamkit fleet sim`: a fleet of simulated ground robots on this machine, each its own
//! `slamkit fleet robot` process and Zenoh peer on `127.0.0.1` (scouting off), plus one
//! `slamkit fleet merger` process, then the merged map scored against the simulator's truth.
//!
//! The world's drive path is cut into `--robots` stretches of equal length that overlap by
//! [`OVERLAP_M`] at each end (the shared places the merge needs); robot `k` drives its stretch
//! out and back (so it also closes its own loop), with sensor noise of its own. The simulator
//! writes each robot's 2D lidar log with wheel odometry (`sim/robot_k.clf`) and its truth
//! (`sim/robot_k.tum`) first; the robot processes then play their logs at `--rate` times real
//! time, all starting together, each starting its map at its own origin (no robot knows where
//! the others are). Once every robot has played its log the merger is stopped (it fetches what
//! it still lacks by query, merges, writes `merger/`) and then the robots.
//!
//! `--loss P` makes every robot's sender drop that fraction of its publications;
//! `--disconnect S` takes the last robot off the network (its Zenoh session closed) for `S`
//! simulated seconds from a quarter of its run, then it joins again; `--restart` kills robot 0
//! (SIGKILL) at 40 % of its run and starts it again on its store, and kills the merger at 70 %
//! and starts a new one. Whatever happens on the way, the final merged map must be the one of a
//! loss-free run (the robots' maps do not depend on the network, and the merger ends with all
//! their messages).

use crate::output::finish;
use anyhow::{bail, Context};
use serde_json::{json, Value};
use slamkit_core::pose::pose3_to_pose2;
use slamkit_core::{Pose2, Trajectory};
use slamkit_eval::association::Pairing;
use slamkit_eval::ate::{ate, Alignment};
use slamkit_io::output_folder::OutputFolder;
use slamkit_io::trajectory_file::{read_trajectory, write_tum};
use slamkit_sim::{RobotKind, SimConfig, Simulation, WaypointMotion, World};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

/// How far \[m\] each robot's stretch of the drive path reaches into its neighbours'.
pub const OVERLAP_M: f64 = 4.0;
/// An accepted inter-robot closure is wrong when its relative pose is further than this from
/// the true one \[m\], or [`WRONG_CLOSURE_RAD`] in heading (an ICP fix is good to centimetres).
const WRONG_CLOSURE_M: f64 = 0.25;
/// See [`WRONG_CLOSURE_M`] \[rad\] (5°).
const WRONG_CLOSURE_RAD: f64 = 0.0873;
/// The merger's settings laid over the defaults: place queries every metre of a robot's path
/// instead of every 3 m. The defaults suit buildings like Intel's (30 m across); in a 13 m
/// office with stretches that share 8 m of corridor, 3 m gives one or two queries per shared
/// stretch, fewer than the three mutually consistent closures a merge needs. And each pair of
/// robots searched both ways: robot 0's corridor submaps are often not pinned down in robot 1's
/// map but robot 1's are in robot 0's, and the other way round (seeds 1-2 of office with 3
/// robots: robot 0 unmerged one way, merged with no wrong closure both ways;
/// docs/experiments/merge-both-ways.md).
const MERGE_SETTINGS: &str = "[places]\nspacing_m = 1.0\nboth_ways = true\n";
/// How long each wait on a process may last at most.
const PATIENCE: Duration = Duration::from_secs(600);

/// What `fleet sim` is asked to run.
#[derive(Debug, Clone)]
pub struct FleetSim {
    /// World: `small`, `large`, `office`, or a TOML world file.
    pub world: String,
    /// Robots in the fleet (2 or more).
    pub robots: usize,
    /// Seed of the robots' sensor noise.
    pub seed: u64,
    /// Fraction of publications each robot's sender drops.
    pub loss: Option<f64>,
    /// Simulated seconds the last robot spends off the network.
    pub disconnect_s: Option<f64>,
    /// Kill and restart robot 0 and the merger mid-run.
    pub restart: bool,
    /// Simulated seconds per wall second.
    pub rate: f64,
    /// Seconds between the merger's merges while updates arrive.
    pub merge_every_s: f64,
    /// The fleet's name.
    pub fleet: String,
    /// The output folder.
    pub out: PathBuf,
}

/// One simulated robot: its name, route, and the files the simulator wrote for it.
struct SimRobot {
    name: String,
    route: Vec<[f64; 2]>,
    log: PathBuf,
    truth: Trajectory,
    duration_s: f64,
}

/// Runs `slamkit fleet sim`.
pub fn run(sim: &FleetSim, stop: &AtomicBool) -> anyhow::Result<()> {
    let started = Instant::now();
    if sim.robots < 2 {
        bail!("--robots {}: a fleet needs 2 robots or more", sim.robots);
    }
    if !(sim.rate.is_finite() && sim.rate > 0.0) {
        bail!("--rate {}: must be > 0", sim.rate);
    }
    if let Some(s) = sim.disconnect_s.filter(|s| !(s.is_finite() && *s > 0.0)) {
        bail!("--disconnect {s}: must be a number of seconds > 0");
    }
    let world = World::by_name_or_file(&sim.world)?;
    let folder = OutputFolder::create(&sim.out, &["report.json"])?;
    let at = |name: &str| sim.out.join(name);
    let robots = simulate(&world, sim.robots, sim.seed, &at("sim"))?;
    for robot in &robots {
        // a store or merged map left by an earlier run would be resumed: start afresh
        for file in ["updates.skmu", "merged.skmap", "report.json"] {
            let path = at(&robot.name).join(file);
            if path.exists() {
                std::fs::remove_file(&path)
                    .with_context(|| format!("removing {}", path.display()))?;
            }
        }
    }
    std::fs::write(at("merge.toml"), MERGE_SETTINGS).context("writing merge.toml")?;
    let endpoint = format!("tcp/127.0.0.1:{}", free_loopback_port()?);
    let merger_args = || -> Vec<String> {
        let mut args = strings(&["fleet", "merger", "--fleet", &sim.fleet]);
        args.extend(strings(&["--listen", &endpoint, "--merge-every"]));
        args.push(sim.merge_every_s.to_string());
        args.extend(["--config".into(), path_arg(&at("merge.toml"))]);
        args.extend(["--out".into(), path_arg(&at("merger"))]);
        args
    };
    let mut fleet = Processes::default();
    fleet.start("merger", &merger_args(), &at("merger.log"))?;
    fleet.wait_for_endpoint(&endpoint, "merger")?;
    let last = robots.len() - 1;
    let robot_args = |k: usize| -> Vec<String> {
        let robot = &robots[k];
        let mut args = strings(&["fleet", "robot"]);
        args.push(path_arg(&robot.log));
        args.extend(strings(&["--fleet", &sim.fleet, "--robot", &robot.name]));
        args.extend(strings(&["--connect", &endpoint, "--rate"]));
        args.push(sim.rate.to_string());
        args.extend(["--out".into(), path_arg(&at(&robot.name))]);
        if let Some(p) = sim.loss {
            args.extend(["--loss".into(), p.to_string()]);
        }
        if let (Some(s), true) = (sim.disconnect_s, k == last) {
            let from = robot.duration_s / 4.0;
            args.extend(["--disconnect".into(), format!("{from},{s}")]);
        }
        args
    };
    for (k, robot) in robots.iter().enumerate() {
        let log = at(&format!("{}.log", robot.name));
        fleet.start(&robot.name, &robot_args(k), &log)?;
    }
    let run_wall_s = robots.iter().map(|r| r.duration_s).fold(0.0, f64::max) / sim.rate;
    let reports: Vec<PathBuf> = robots
        .iter()
        .map(|r| at(&r.name).join("report.json"))
        .collect();
    let mut restarts = Vec::new();
    if sim.restart {
        let robot0_wall = robots[0].duration_s / sim.rate;
        fleet.sleep(Duration::from_secs_f64(0.4 * robot0_wall), stop)?;
        fleet.kill(&robots[0].name)?;
        restarts
            .push(json!({"killed": robots[0].name, "at_wall_s": started.elapsed().as_secs_f64()}));
        let log = at(&format!("{}_restarted.log", robots[0].name));
        fleet.start(&robots[0].name, &robot_args(0), &log)?;
        fleet.sleep(Duration::from_secs_f64(0.3 * run_wall_s), stop)?;
        fleet.kill("merger")?;
        restarts.push(json!({"killed": "merger", "at_wall_s": started.elapsed().as_secs_f64()}));
        fleet.sleep(Duration::from_secs(1), stop)?;
        fleet.start("merger", &merger_args(), &at("merger_restarted.log"))?;
    }
    fleet.wait_until("every robot's log played", stop, || {
        reports.iter().all(|r| r.exists())
    })?;
    fleet.interrupt("merger")?;
    fleet.wait_for_exit("merger", stop)?;
    for robot in &robots {
        fleet.interrupt(&robot.name)?;
        fleet.wait_for_exit(&robot.name, stop)?;
    }

    let merged = read_json(&at("merger").join("report.json"))?;
    let mut robot_reports = Vec::new();
    for robot in &robots {
        robot_reports.push(read_json(&at(&robot.name).join("report.json"))?);
    }
    let mut report = score(sim, &robots, &robot_reports, &merged)?;
    report["restarts"] = json!(restarts);
    report["wall_seconds"] = json!(started.elapsed().as_secs_f64());
    let summary = format!(
        "{} robots in {}: merged map mean position error {:.3} m over {} keyframes; {} inter-robot \
         closures accepted, {} wrong; outputs in {}",
        robots.len(),
        sim.world,
        report["metrics"]["merged_mean_position_error_m"]
            .as_f64()
            .unwrap_or(f64::NAN),
        report["metrics"]["merged_poses"],
        report["metrics"]["inter_robot_closures_accepted"],
        report["metrics"]["inter_robot_closures_accepted_wrong"],
        sim.out.display()
    );
    finish(folder, &report)?;
    println!("{summary}");
    Ok(())
}

/// Cuts `path` (a polyline) into `n` stretches of equal length, each reaching `overlap_m`
/// further at both ends (within the path), and returns each as a route out and back.
///
pub fn routes(path: &[[f64; 2]], n: usize, overlap_m: f64) -> Vec<Vec<[f64; 2]>> {
    let lengths: Vec<f64> = path
        .windows(2)
        .map(|w| (w[1][0] - w[0][0]).hypot(w[1][1] - w[0][1]))
        .collect();
    let total: f64 = lengths.iter().sum();
    let point_at = |s: f64| -> [f64; 2] {
        let mut left = s;
        for (w, len) in path.windows(2).zip(&lengths) {
            if left <= *len && *len > 0.0 {
                let f = left / len;
                return [
                    w[0][0] + f * (w[1][0] - w[0][0]),
                    w[0][1] + f * (w[1][1] - w[0][1]),
                ];
            }
            left -= len;
        }
        path[path.len() - 1]
    };
    (0..n)
        .map(|k| {
            let from = (total * k as f64 / n as f64 - overlap_m).max(0.0);
            let to = (total * (k + 1) as f64 / n as f64 + overlap_m).min(total);
            let mut out = vec![point_at(from)];
            let mut s = 0.0;
            for (i, len) in lengths.iter().enumerate() {
                s += len;
                if s > from + 1e-9 && s < to - 1e-9 {
                    out.push(path[i + 1]);
                }
            }
            out.push(point_at(to));
            let back: Vec<[f64; 2]> = out.iter().rev().skip(1).copied().collect();
            out.extend(back);
            out
        })
        .collect()
}

/// Simulates the robots' runs: writes each one's lidar log and truth into `dir`.
fn simulate(world: &World, n: usize, seed: u64, dir: &Path) -> anyhow::Result<Vec<SimRobot>> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let config = SimConfig {
        robot: RobotKind::DiffDrive,
        ..SimConfig::default()
    };
    if world.drive_path.len() < 2 {
        bail!("world {} has no drive path for ground robots", world.name);
    }
    let mut robots = Vec::new();
    for (k, route) in routes(&world.drive_path, n, OVERLAP_M)
        .into_iter()
        .enumerate()
    {
        let name = format!("robot_{k}");
        let motion = WaypointMotion::diff_drive(&route, &config.diff_drive)?;
        let robot_seed = seed.wrapping_mul(1000).wrapping_add(k as u64);
        let sim = Simulation::with_motion(world.clone(), motion, config.clone(), robot_seed)?;
        let times = sim.sample_times(config.lidar.rate_hz);
        let scans = sim.lidar_scans(&times);
        let truth = sim.ground_truth(&times);
        let log = dir.join(format!("{name}.clf"));
        slamkit_io::carmen_writer::write_carmen(&log, &scans)?;
        write_tum(&dir.join(format!("{name}.tum")), &truth)?;
        robots.push(SimRobot {
            name,
            route,
            log,
            truth,
            duration_s: sim.duration_s(),
        });
    }
    Ok(robots)
}

/// The report: every robot's error in its own frame and in the merged one, the merged map's
/// error (one rigid alignment of all robots' poses onto the truth), the inter-robot closures
/// checked against the truth, bytes and merge latencies.
fn score(
    sim: &FleetSim,
    robots: &[SimRobot],
    robot_reports: &[Value],
    merged: &Value,
) -> anyhow::Result<Value> {
    let merger_dir = sim.out.join("merger");
    let pairing = Pairing::NearestTime { max_diff_s: 1e-4 };
    let mut per_robot = Vec::new();
    let (mut estimated, mut truth) = (Vec::new(), Vec::new());
    let mut owner = Vec::new();
    for (k, (robot, report)) in robots.iter().zip(robot_reports).enumerate() {
        let (own, _) = read_trajectory(&sim.out.join(&robot.name).join("trajectory.tum"))?;
        let own_error = ate(&robot.truth, &own, pairing, Alignment::Se3)?;
        let in_merged = merger_dir.join(format!("trajectory_{}.tum", robot.name));
        if in_merged.exists() {
            let (poses, _) = read_trajectory(&in_merged)?;
            let t: Vec<f64> = robot.truth.poses.iter().map(|p| p.timestamp).collect();
            let e: Vec<f64> = poses.poses.iter().map(|p| p.timestamp).collect();
            for (i, j) in slamkit_eval::association::matching_time_indices(&e, &t, 1e-4) {
                estimated.push(poses.poses[i].pose.translation.vector.into());
                truth.push(robot.truth.poses[j].pose.translation.vector.into());
                owner.push(k);
            }
        }
        let fleet = &report["fleet"];
        per_robot.push(json!({
            "name": robot.name,
            "route": robot.route,
            "log_seconds": robot.duration_s,
            "scans": robot.truth.poses.len(),
            "own_frame_ate": own_error.stats,
            "update_bytes": fleet["update_bytes"],
            "bytes_published": fleet["bytes_published"],
            "update_bytes_per_log_second": fleet["update_bytes_per_log_second"],
            "laser_scan_bytes_per_log_second": fleet["laser_scan_bytes_per_log_second"],
            "update_fraction_of_laser_scans": fleet["update_fraction_of_laser_scans"],
            "messages_stored": fleet["messages_stored"],
            "messages_published": fleet["messages_published"],
            "messages_dropped_on_purpose": fleet["messages_dropped_on_purpose"],
            "messages_held_back_while_disconnected": fleet["messages_held_back_while_disconnected"],
            "resumed_from_message": fleet["resumed_from_message"],
            "merged_map_received": fleet["merged_map"],
        }));
    }
    let (mut merged_errors, mut fit) = (Vec::new(), None);
    if estimated.len() >= 3 {
        let f = slamkit_core::umeyama(&estimated, &truth, false)
            .context("aligning the merged map to the truth")?;
        merged_errors = estimated
            .iter()
            .zip(&truth)
            .map(|(e, t)| (f.transform_point(e) - t).norm())
            .collect();
        fit = Some(f);
    }
    for (k, entry) in per_robot.iter_mut().enumerate() {
        let errors: Vec<f64> = merged_errors
            .iter()
            .zip(&owner)
            .filter(|(_, o)| **o == k)
            .map(|(e, _)| *e)
            .collect();
        entry["merged_frame_mean_position_error_m"] = json!(mean(&errors));
    }
    let closures = check_closures(robots, merged)?;
    let fleet = &merged["fleet"];
    let max = merged_errors.iter().copied().fold(0.0, f64::max);
    Ok(json!({
        "input": {
            "world": sim.world,
            "robots": sim.robots,
            "seed": sim.seed,
            "loss": sim.loss,
            "disconnect_s": sim.disconnect_s,
            "restart": sim.restart,
        },
        "config": {
            "robot": "diff-drive ground robot with a 2D lidar and wheel odometry",
            "overlap_m": OVERLAP_M,
            "rate": sim.rate,
            "merge_every_s": sim.merge_every_s,
            "merge_settings": MERGE_SETTINGS,
            "fleet": sim.fleet,
            "wrong_closure_m": WRONG_CLOSURE_M,
            "wrong_closure_rad": WRONG_CLOSURE_RAD,
        },
        "metrics": {
            "merged_mean_position_error_m": mean(&merged_errors),
            "merged_max_position_error_m": max,
            "merged_poses": merged_errors.len(),
            "unmerged": merged["unmerged"],
            "inter_robot_closures_found": closures.found,
            "inter_robot_closures_accepted": closures.accepted,
            "inter_robot_closures_rejected": closures.found - closures.accepted,
            "inter_robot_closures_accepted_wrong": closures.accepted_wrong,
            "inter_robot_closures_rejected_right": closures.rejected_right,
            "receipt_to_merged_ms": fleet["receipt_to_merged_ms"],
            "publish_to_receipt_ms": fleet["publish_to_receipt_ms"],
            "merges": fleet["merges"],
            "messages_missing_at_merger": fleet["missing"],
        },
        "merged_from_truth": fit.map(|f| {
            let p = pose3_to_pose2(&f.dst_from_src);
            json!({"x_m": p.translation.x, "y_m": p.translation.y, "theta_rad": p.rotation.angle()})
        }),
        "robots": per_robot,
        "closures": closures.list,
        "frames": { "read": robots.iter().map(|r| r.truth.poses.len()).sum::<usize>() },
        "timings_ms": merged["timings_ms"],
    }))
}

/// Inter-robot closures of a merge report, each checked against the truth.
struct ClosureCheck {
    found: usize,
    accepted: usize,
    accepted_wrong: usize,
    rejected_right: usize,
    list: Vec<Value>,
}

fn check_closures(robots: &[SimRobot], merged: &Value) -> anyhow::Result<ClosureCheck> {
    let truth_at = |name: &str, t: f64| -> Option<Pose2> {
        let robot = robots.iter().find(|r| r.name == name)?;
        let p = robot
            .truth
            .poses
            .iter()
            .min_by(|a, b| (a.timestamp - t).abs().total_cmp(&(b.timestamp - t).abs()))?;
        Some(pose3_to_pose2(&p.pose))
    };
    let mut check = ClosureCheck {
        found: 0,
        accepted: 0,
        accepted_wrong: 0,
        rejected_right: 0,
        list: Vec::new(),
    };
    for c in merged["closures"].as_array().into_iter().flatten() {
        let (from, to) = (c["from"].as_str(), c["to"].as_str());
        let (Some(from), Some(to)) = (from, to) else {
            bail!("merge report: a closure without robot names: {c}");
        };
        if from == to {
            continue;
        }
        let time = |k: &str| {
            c[k].as_f64()
                .context("merge report: a closure without times")
        };
        let (Some(a), Some(b)) = (
            truth_at(from, time("from_time_s")?),
            truth_at(to, time("to_time_s")?),
        ) else {
            bail!("merge report: closure between unknown robots {from} and {to}");
        };
        let m = &c["from_from_to"];
        let num = |k: &str| {
            m[k].as_f64()
                .context("merge report: a closure without its pose")
        };
        let measured = Pose2::new(
            nalgebra::Vector2::new(num("x_m")?, num("y_m")?),
            num("theta_rad")?,
        );
        let error = (a.inverse() * b).inverse() * measured;
        let (e_m, e_rad) = (
            error.translation.vector.norm(),
            error.rotation.angle().abs(),
        );
        let right = e_m <= WRONG_CLOSURE_M && e_rad <= WRONG_CLOSURE_RAD;
        let accepted = c["status"] == "accepted";
        check.found += 1;
        check.accepted += usize::from(accepted);
        check.accepted_wrong += usize::from(accepted && !right);
        check.rejected_right += usize::from(!accepted && right);
        check.list.push(json!({
            "from": from, "to": to,
            "from_time_s": c["from_time_s"], "to_time_s": c["to_time_s"],
            "status": c["status"],
            "error_m": e_m, "error_rad": e_rad, "right": right,
        }));
    }
    Ok(check)
}

fn mean(values: &[f64]) -> Option<f64> {
    (!values.is_empty()).then(|| values.iter().sum::<f64>() / values.len() as f64)
}

fn read_json(path: &Path) -> anyhow::Result<Value> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))
}

fn strings(args: &[&str]) -> Vec<String> {
    args.iter().map(|a| a.to_string()).collect()
}

fn path_arg(path: &Path) -> String {
    path.to_string_lossy().into_owned()
}

/// A port on 127.0.0.1 free a moment ago (the OS's choice).
fn free_loopback_port() -> anyhow::Result<u16> {
    let listener =
        std::net::TcpListener::bind("127.0.0.1:0").context("finding a free loopback port")?;
    Ok(listener.local_addr()?.port())
}

/// The fleet's processes by name (a restarted one replaces its predecessor); every one still
/// running is killed when this is dropped (an error or Ctrl-C leaves none behind).
#[derive(Default)]
struct Processes {
    children: Vec<(String, Child, PathBuf)>,
}

impl Processes {
    /// Starts `slamkit ARGS` (this very executable) as `name`, its output in the file `log`.
    fn start(&mut self, name: &str, args: &[String], log: &Path) -> anyhow::Result<()> {
        let log = log.to_path_buf();
        let stdout =
            std::fs::File::create(&log).with_context(|| format!("creating {}", log.display()))?;
        let child = Command::new(std::env::current_exe().context("finding slamkit's executable")?)
            .args(args)
            .stdin(Stdio::null())
            .stdout(stdout.try_clone()?)
            .stderr(stdout)
            .spawn()
            .with_context(|| format!("starting the {name} process"))?;
        self.children.retain(|(n, _, _)| n != name);
        self.children.push((name.to_string(), child, log));
        Ok(())
    }

    fn child(&mut self, name: &str) -> anyhow::Result<&mut (String, Child, PathBuf)> {
        self.children
            .iter_mut()
            .find(|(n, _, _)| n == name)
            .with_context(|| format!("no process {name}"))
    }

    /// Stops `name` at once (SIGKILL): a crash.
    fn kill(&mut self, name: &str) -> anyhow::Result<()> {
        let (_, child, _) = self.child(name)?;
        child.kill()?;
        child.wait()?;
        self.children.retain(|(n, _, _)| n != name);
        Ok(())
    }

    /// Asks `name` to stop (SIGINT, as Ctrl-C), so it writes its outputs.
    fn interrupt(&mut self, name: &str) -> anyhow::Result<()> {
        let id = self.child(name)?.1.id().to_string();
        let status = Command::new("kill").args(["-INT", &id]).status()?;
        if !status.success() {
            bail!("could not interrupt the {name} process");
        }
        Ok(())
    }

    /// Fails, with the end of every process's output, when one has exited.
    fn all_running(&mut self) -> anyhow::Result<()> {
        for (name, child, log) in &mut self.children {
            if let Some(status) = child.try_wait()? {
                let text = std::fs::read_to_string(&*log).unwrap_or_default();
                let tail: Vec<&str> = text.lines().rev().take(5).collect();
                bail!(
                    "the {name} process ended ({status}) before its time: {}",
                    tail.into_iter().rev().collect::<Vec<_>>().join(" | ")
                );
            }
        }
        Ok(())
    }

    fn wait_until(
        &mut self,
        what: &str,
        stop: &AtomicBool,
        mut done: impl FnMut() -> bool,
    ) -> anyhow::Result<()> {
        let start = Instant::now();
        while !done() {
            self.all_running()?;
            if stop.load(Ordering::Relaxed) {
                bail!("interrupted while waiting for {what}");
            }
            if start.elapsed() > PATIENCE {
                bail!("timed out waiting for {what}");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
        Ok(())
    }

    fn sleep(&mut self, time: Duration, stop: &AtomicBool) -> anyhow::Result<()> {
        let until = Instant::now() + time;
        self.wait_until("the next step", stop, || Instant::now() >= until)
    }

    fn wait_for_endpoint(&mut self, endpoint: &str, name: &str) -> anyhow::Result<()> {
        let address = endpoint.trim_start_matches("tcp/").to_string();
        let never = AtomicBool::new(false);
        self.wait_until(&format!("the {name}'s endpoint"), &never, || {
            std::net::TcpStream::connect(&address).is_ok()
        })
    }

    /// Waits for `name` to exit, which it must do successfully.
    fn wait_for_exit(&mut self, name: &str, stop: &AtomicBool) -> anyhow::Result<()> {
        let start = Instant::now();
        let (_, child, log) = self.child(name)?;
        loop {
            if let Some(status) = child.try_wait()? {
                if !status.success() {
                    let text = std::fs::read_to_string(&*log).unwrap_or_default();
                    bail!("the {name} process failed ({status}): {}", text.trim_end());
                }
                return Ok(());
            }
            if stop.load(Ordering::Relaxed) || start.elapsed() > PATIENCE {
                bail!("the {name} process did not stop");
            }
            std::thread::sleep(Duration::from_millis(50));
        }
    }
}

impl Drop for Processes {
    fn drop(&mut self) {
        for (_, child, _) in &mut self.children {
            if matches!(child.try_wait(), Ok(None)) {
                let _ = child.kill();
                let _ = child.wait();
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_is_cut_into_overlapping_stretches_driven_out_and_back() {
        let routes = routes(&[[0.0, 0.0], [10.0, 0.0]], 2, 1.0);
        assert_eq!(routes[0], [[0.0, 0.0], [6.0, 0.0], [0.0, 0.0]]);
        assert_eq!(routes[1], [[4.0, 0.0], [10.0, 0.0], [4.0, 0.0]]);
        // a corner inside a stretch is kept, one at its end is not repeated
        let bent = super::routes(&[[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]], 2, 0.0);
        assert_eq!(bent[0], [[0.0, 0.0], [4.0, 0.0], [0.0, 0.0]]);
        assert_eq!(bent[1], [[4.0, 0.0], [4.0, 4.0], [4.0, 0.0]]);
        let three = super::routes(&[[0.0, 0.0], [4.0, 0.0], [4.0, 4.0]], 1, 0.0);
        assert_eq!(
            three[0],
            [[0.0, 0.0], [4.0, 0.0], [4.0, 4.0], [4.0, 0.0], [0.0, 0.0]]
        );
    }
}
