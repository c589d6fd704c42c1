//! `tessera farm` against a real Redis (Debian's `redis-server`, started per test on a free
//! loopback port with its append-only file in a temporary directory), with workers as
//! separate processes that the tests kill.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{pixels, root, scratch};

/// A `redis-server` on a free loopback port, stopped on drop.
struct RedisServer {
    child: Child,
    port: u16,
    dir: PathBuf,
}

impl RedisServer {
    fn start(dir: &Path) -> RedisServer {
        let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
        let dir = dir.join("redis");
        std::fs::create_dir_all(&dir).unwrap();
        let mut server = RedisServer { child: Self::spawn(port, &dir), port, dir };
        server.wait_ready();
        server
    }

    fn spawn(port: u16, dir: &Path) -> Child {
        Command::new("redis-server")
            .args(["--port", &port.to_string(), "--bind", "127.0.0.1", "--save", "", "--appendonly", "yes", "--dir"])
            .arg(dir)
            .stdout(Stdio::null())
            .spawn()
            .expect("redis-server is installed (.ci/run installs Debian's redis-server)")
    }

    fn wait_ready(&mut self) {
        let deadline = Instant::now() + Duration::from_secs(10);
        while std::net::TcpStream::connect(("127.0.0.1", self.port)).is_err() {
            assert!(Instant::now() < deadline, "redis-server did not start");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    fn url(&self) -> String {
        format!("redis://127.0.0.1:{}", self.port)
    }

    /// Stops Redis (SIGTERM: it flushes its append-only file) and starts it again on the same
    /// port and directory after `down`.
    fn restart(&mut self, down: Duration) {
        unsafe { libc::kill(self.child.id() as i32, libc::SIGTERM) };
        self.child.wait().unwrap();
        std::thread::sleep(down);
        self.child = Self::spawn(self.port, &self.dir);
        self.wait_ready();
    }
}

impl Drop for RedisServer {
    fn drop(&mut self) {
        self.child.kill().ok();
        self.child.wait().ok();
    }
}

fn tessera(args: &[&str]) -> std::process::Output {
    let out = Command::new(env!("CARGO_BIN_EXE_tessera")).args(args).output().expect("the CLI runs");
    assert!(out.status.success(), "tessera {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    out
}

/// Submits a job and returns its id.
fn submit(redis: &RedisServer, scene: &Path, frames: &str, output: &Path, extra: &[&str]) -> String {
    let mut args = vec!["farm", "submit", scene.to_str().unwrap(), "--frames", frames, "-o", output.to_str().unwrap(), "--redis"];
    let url = redis.url();
    args.push(&url);
    args.extend_from_slice(extra);
    String::from_utf8(tessera(&args).stdout).unwrap().trim().to_string()
}

fn worker(redis: &RedisServer, name: &str, extra: &[&str]) -> Child {
    Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(["farm", "worker", "--redis", &redis.url(), "--name", name])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap()
}

/// Waits (bounded) for workers that exit once idle.
fn finish(workers: Vec<Child>) {
    for mut w in workers {
        let deadline = Instant::now() + Duration::from_secs(300);
        while w.try_wait().unwrap().is_none() {
            assert!(Instant::now() < deadline, "a worker never went idle");
            std::thread::sleep(Duration::from_millis(20));
        }
    }
}

fn status(redis: &RedisServer, job: &str) -> String {
    String::from_utf8(tessera(&["farm", "status", job, "--redis", &redis.url()]).stdout).unwrap()
}

/// The rows of `farm status`: (frame, slice, state, worker, attempts).
fn rows(status: &str) -> Vec<Vec<String>> {
    status.lines().skip(2).filter(|l| l.starts_with("  ")).map(|l| l.split_whitespace().map(str::to_string).collect()).collect()
}

/// Three workers, twelve frames: every frame rendered and acknowledged once (one attempt
/// each, nothing left pending), and each EXR equals `tessera render --frames`' bit for bit.
#[test]
fn three_workers_render_twelve_frames_once_each() {
    let dir = scratch("farm", "twelve");
    let redis = RedisServer::start(&dir);
    let scene = root().join("fixtures/usd/animated.usda");
    let job = submit(&redis, &scene, "1-12", &dir.join("farm/f.####.exr"), &["--spp", "8", "--", "--res", "16x12"]);
    let workers = ["a", "b", "c"].map(|n| worker(&redis, n, &["--exit-when-idle", "2"])).into();
    finish(workers);
    let report = status(&redis, &job);
    let rows = rows(&report);
    assert_eq!(rows.len(), 12, "{report}");
    assert!(rows.iter().all(|r| r[2] == "done" && r[5] == "1"), "each frame once: {report}");
    assert!(report.contains("12 of 12 tasks done"), "{report}");
    let pending =
        Command::new("redis-cli").args(["-p", &redis.port.to_string(), "XPENDING", "tessera:tasks:5", "workers"]).output().unwrap();
    assert!(String::from_utf8_lossy(&pending.stdout).starts_with('0'), "nothing pending: {}", String::from_utf8_lossy(&pending.stdout));
    let local = dir.join("local/f.####.exr");
    tessera(&["render", scene.to_str().unwrap(), "--frames", "1-12", "--spp", "8", "--res", "16x12", "-o", local.to_str().unwrap()]);
    for f in 1..=12 {
        let name = format!("f.{f:04}.exr");
        assert!(pixels(&dir.join("farm").join(&name)) == pixels(&dir.join("local").join(&name)), "frame {f} differs");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// A worker killed (SIGKILL) mid-frame: its render dies with it, another worker claims the
/// task once it has been silent for --claim-after, resumes from the checkpoint, and the EXR
/// equals a clean render's bit for bit. A watcher checks every file that appears at the
/// final path: each is a whole EXR.
#[test]
fn a_killed_worker_s_frame_resumes_elsewhere_bit_for_bit() {
    let dir = scratch("farm", "kill");
    let redis = RedisServer::start(&dir);
    let scene = root().join("fixtures/cornell_box.usda");
    let output = dir.join("out/frame.####.exr");
    let job = submit(&redis, &scene, "1", &output, &["--spp", "512", "--", "--res", "48x48"]);
    let final_path = dir.join("out/frame.0001.exr");
    let checkpoint = dir.join("out/frame.0001.exr.checkpoint");
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let watcher = {
        let (path, stop) = (final_path.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut seen = 0;
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                if path.exists() {
                    tessera::output::read_exr(&path).expect("a whole EXR at the final path");
                    seen += 1;
                }
                std::thread::sleep(Duration::from_millis(2));
            }
            seen
        })
    };
    let mut first = worker(&redis, "doomed", &["--checkpoint-interval", "0", "--claim-after", "1"]);
    let deadline = Instant::now() + Duration::from_secs(120);
    let end = |p: &Path| tessera::film::ExactFilm::load(p).ok().map(|f| f.range.end);
    while end(&checkpoint).is_none_or(|e| e < 64) {
        assert!(Instant::now() < deadline && first.try_wait().unwrap().is_none(), "no checkpoint before the render ended");
        std::thread::sleep(Duration::from_millis(5));
    }
    first.kill().unwrap();
    first.wait().unwrap();
    let killed_at = end(&checkpoint).unwrap();
    assert!(!final_path.exists(), "the killed worker's render did not finish");
    finish(vec![worker(&redis, "rescuer", &["--checkpoint-interval", "0", "--claim-after", "1", "--exit-when-idle", "3"])]);
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    assert!(watcher.join().unwrap() > 0, "the watcher saw the frame");
    let report = status(&redis, &job);
    let row = &rows(&report)[0];
    assert_eq!((row[2].as_str(), row[3].as_str(), row[5].as_str()), ("done", "rescuer", "2"), "{report}");
    let clean = dir.join("clean.exr");
    tessera(&["render", scene.to_str().unwrap(), "--frame", "1", "--spp", "512", "--res", "48x48", "-o", clean.to_str().unwrap()]);
    assert!(pixels(&clean) == pixels(&final_path), "resumed from sample {killed_at}, the frame differs");
    assert!(!checkpoint.exists());
    std::fs::remove_dir_all(&dir).ok();
}

/// Poison tasks end in the dead-letter stream with their error: a scene that does not parse
/// at once (retrying cannot help), a render that keeps failing transiently (no server at
/// the URL) after exactly three attempts. The good job's frames finish.
#[test]
fn poison_tasks_go_to_the_dead_letter_stream() {
    let dir = scratch("farm", "poison");
    let redis = RedisServer::start(&dir);
    let bad = submit(&redis, &root().join("fixtures/bad/malformed.usda"), "1", &dir.join("bad.####.exr"), &["--spp", "1"]);
    let good =
        submit(&redis, &root().join("fixtures/cornell_box.usda"), "1-2", &dir.join("good.####.exr"), &["--spp", "2", "--", "--res", "8x8"]);
    finish(vec![worker(&redis, "w", &["--exit-when-idle", "1"])]);
    assert!(status(&redis, &good).contains("2 of 2 tasks done"), "{}", status(&redis, &good));
    let report = status(&redis, &bad);
    let row = &rows(&report)[0];
    assert_eq!((row[2].as_str(), row[5].as_str()), ("failed", "1"), "a bad scene fails at once: {report}");
    assert!(report.contains("failed to parse"), "{report}");

    // Rendering through a server that is not there fails with the transient exit status.
    let flaky = submit(&redis, &root().join("fixtures/cornell_box.usda"), "1", &dir.join("flaky.####.exr"), &["--spp", "1"]);
    finish(vec![worker(&redis, "w", &["--server", "http://127.0.0.1:1", "--claim-after", "0.2", "--exit-when-idle", "2"])]);
    let report = status(&redis, &flaky);
    let row = &rows(&report)[0];
    assert_eq!(row[2], "failed", "{report}");
    assert!(report.contains("gave up after 3 attempts"), "{report}");
    let dead = Command::new("redis-cli").args(["-p", &redis.port.to_string(), "XRANGE", "tessera:dead", "-", "+"]).output().unwrap();
    let dead = String::from_utf8_lossy(&dead.stdout);
    assert!(dead.contains(&format!("tessera:task:{bad}:0")) && dead.contains(&format!("tessera:task:{flaky}:0")), "{dead}");
    assert!(!dead.contains(&format!("tessera:task:{good}:")), "{dead}");
    std::fs::remove_dir_all(&dir).ok();
}

/// A frame split into 4 sample slices on 3 workers merges to the single-process render bit
/// for bit, and the slices' films are removed once merged.
#[test]
fn split_frames_merge_to_the_single_process_render() {
    let dir = scratch("farm", "split");
    let redis = RedisServer::start(&dir);
    let scene = root().join("fixtures/cornell_box.usda");
    let job = submit(
        &redis,
        &scene,
        "1",
        &dir.join("out/s.####.exr"),
        &["--spp", "256", "--split-samples", "4", "--", "--res", "24x24", "--aov", "albedo"],
    );
    finish(["a", "b", "c"].map(|n| worker(&redis, n, &["--exit-when-idle", "2"])).into());
    let report = status(&redis, &job);
    assert_eq!(rows(&report).iter().map(|r| r[1].clone()).collect::<Vec<_>>(), ["0-64", "64-128", "128-192", "192-256"], "{report}");
    assert!(report.contains("4 of 4 tasks done"), "{report}");
    let single = dir.join("single.exr");
    tessera(&[
        "render",
        scene.to_str().unwrap(),
        "--frame",
        "1",
        "--spp",
        "256",
        "--res",
        "24x24",
        "--aov",
        "albedo",
        "-o",
        single.to_str().unwrap(),
    ]);
    assert!(pixels(&single) == pixels(&dir.join("out/s.0001.exr")));
    let left: Vec<String> = std::fs::read_dir(dir.join("out")).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
    assert!(left.iter().all(|n| !n.contains(".part")), "{left:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// Redis restarted mid-job (append-only file on): the workers reconnect and the job
/// completes.
#[test]
fn workers_survive_a_redis_restart() {
    let dir = scratch("farm", "restart");
    let mut redis = RedisServer::start(&dir);
    let scene = root().join("fixtures/usd/animated.usda");
    let job = submit(&redis, &scene, "1-8", &dir.join("out/f.####.exr"), &["--spp", "64", "--", "--res", "32x32"]);
    let workers: Vec<Child> = ["a", "b"].map(|n| worker(&redis, n, &["--exit-when-idle", "3"])).into();
    let deadline = Instant::now() + Duration::from_secs(120);
    while !dir.join("out/f.0001.exr").exists() && !dir.join("out/f.0002.exr").exists() {
        assert!(Instant::now() < deadline, "no frame before the restart");
        std::thread::sleep(Duration::from_millis(10));
    }
    redis.restart(Duration::from_millis(1500));
    finish(workers);
    let report = status(&redis, &job);
    assert!(report.contains("8 of 8 tasks done"), "{report}");
    for f in 1..=8 {
        assert!(dir.join(format!("out/f.{f:04}.exr")).is_file(), "frame {f}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Workers take the highest priority's tasks first: a job submitted after a low-priority one
/// but at priority 9 is rendered entirely before it.
#[test]
fn higher_priority_jobs_go_first() {
    let dir = scratch("farm", "priority");
    let redis = RedisServer::start(&dir);
    let scene = root().join("fixtures/cornell_box.usda");
    let low = submit(&redis, &scene, "1-3", &dir.join("low.####.exr"), &["--spp", "1", "--priority", "1", "--", "--res", "8x8"]);
    let high = submit(&redis, &scene, "1-3", &dir.join("high.####.exr"), &["--spp", "1", "--priority", "9", "--", "--res", "8x8"]);
    finish(vec![worker(&redis, "w", &["--exit-when-idle", "1"])]);
    let started = |job: &str| -> Vec<u64> {
        (0..3)
            .map(|n| {
                let out = Command::new("redis-cli")
                    .args(["-p", &redis.port.to_string(), "HGET", &format!("tessera:task:{job}:{n}"), "started"])
                    .output()
                    .unwrap();
                String::from_utf8_lossy(&out.stdout).trim().parse().unwrap()
            })
            .collect()
    };
    let (low, high) = (started(&low), started(&high));
    assert!(high.iter().max() < low.iter().min(), "high {high:?} before low {low:?}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `farm cancel` drops a job's queued tasks (no output appears); `farm retry --failed` puts
/// failed tasks back with fresh attempts, and once the cause is gone they finish.
#[test]
fn cancelled_jobs_stop_and_failed_tasks_can_be_retried() {
    let dir = scratch("farm", "cancel");
    let redis = RedisServer::start(&dir);
    let scene = root().join("fixtures/cornell_box.usda");
    let cancelled = submit(&redis, &scene, "1-3", &dir.join("c.####.exr"), &["--spp", "1", "--", "--res", "8x8"]);
    tessera(&["farm", "cancel", &cancelled, "--redis", &redis.url()]);
    // Fails three times: no server at this URL (a transient failure).
    let flaky = submit(&redis, &scene, "1", &dir.join("f.####.exr"), &["--spp", "1", "--", "--res", "8x8"]);
    finish(vec![worker(&redis, "w", &["--server", "http://127.0.0.1:1", "--claim-after", "0.2", "--exit-when-idle", "2"])]);
    let report = status(&redis, &cancelled);
    assert!(rows(&report).iter().all(|r| r[2] == "cancelled"), "{report}");
    assert!(!dir.join("c.0001.exr").exists());
    assert!(status(&redis, &flaky).contains("1 failed"), "{}", status(&redis, &flaky));
    let said = String::from_utf8(tessera(&["farm", "retry", &flaky, "--failed", "--redis", &redis.url()]).stdout).unwrap();
    assert!(said.contains("1 failed tasks"), "{said}");
    finish(vec![worker(&redis, "w", &["--exit-when-idle", "1"])]);
    let report = status(&redis, &flaky);
    assert!(report.contains("1 of 1 tasks done"), "{report}");
    assert!(dir.join("f.0001.exr").is_file());
    std::fs::remove_dir_all(&dir).ok();
}
