//! What the farm machinery costs: a 1920x1080 checkpoint (time and bytes, with the default
//! AOVs and with the light-path AOVs), merging four slices of a 1080p frame, and the queue's
//! overhead per task (a real redis-server and worker against the same frames rendered by
//! `tessera render` directly). Prints numbers for docs/farm.md; asserts nothing about time.
//!
//! `cargo bench -p tessera --bench farm` (needs `redis-server` on the PATH for the queue part).

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use glam::Vec3;
use render_core::film::{PixelSample, Rect, TileFilm, tiles_centre_out};
use tessera::film::ExactFilm;
use tessera_proto::v1 as pb;

const W: u32 = 1920;
const H: u32 = 1080;

/// A 1080p film holding one pass of samples `range` in 64-pixel tiles, as a stream delivers it.
fn film(first: u32, range: std::ops::Range<u32>, extra: bool) -> ExactFilm {
    let mut film = ExactFilm::new(W, H, first);
    for rect in tiles_centre_out(W, H, 64) {
        let mut tile = TileFilm::new(rect, extra);
        for i in 0..(rect.width * rect.height) as usize {
            let v = (i % 97) as f32 / 97.0;
            tile.add(i, &PixelSample { radiance: Vec3::splat(v), alpha: 1.0, normal: Vec3::Z, ..Default::default() });
        }
        let Rect { x, y, width, height } = rect;
        let t = pb::FilmTile {
            x,
            y,
            width,
            height,
            pass_index: 0,
            first_sample: range.start,
            end_sample: range.end,
            extra,
            sums: tile.encode(),
        };
        film.add(&t).unwrap();
    }
    film.pass_done(range.end);
    film
}

fn checkpoint(dir: &Path, extra: bool) {
    let f = film(0, 0..64, extra);
    let path = dir.join(format!("checkpoint-{extra}"));
    let t = Instant::now();
    f.save(&path).unwrap();
    let save = t.elapsed();
    let bytes = std::fs::metadata(&path).unwrap().len();
    let t = Instant::now();
    ExactFilm::load(&path).unwrap();
    let load = t.elapsed();
    let aovs = if extra { "beauty + light-path AOVs" } else { "default AOVs (beauty)" };
    println!(
        "checkpoint 1920x1080, {aovs}: {:.1} MB, write+fsync {:.0} ms, read {:.0} ms",
        bytes as f64 / 1e6,
        save.as_secs_f64() * 1e3,
        load.as_secs_f64() * 1e3
    );
}

fn merge(dir: &Path) {
    let ranges = [0..64, 64..128, 128..192, 192..256];
    let parts: Vec<PathBuf> = ranges
        .iter()
        .map(|r| {
            let p = dir.join(format!("part{}", r.start));
            let mut f = film(r.start, r.clone(), false);
            f.metadata = vec![("settingsHash".into(), "bench".into())];
            f.save(&p).unwrap();
            p
        })
        .collect();
    let t = Instant::now();
    tessera::commands::render::merge(&parts, &dir.join("merged.exr"), false).unwrap();
    println!("merge of 4 slices at 1920x1080 (read, add, resolve, write EXR + PNG): {:.0} ms", t.elapsed().as_secs_f64() * 1e3);
}

/// Per-task overhead: 20 small frames through Redis and one worker, against the same 20
/// frames rendered by 20 `tessera render` processes (the worker runs one per task).
async fn queue(dir: &Path) -> anyhow::Result<()> {
    let port = std::net::TcpListener::bind("127.0.0.1:0")?.local_addr()?.port();
    let mut redis = Command::new("redis-server")
        .args(["--port", &port.to_string(), "--bind", "127.0.0.1", "--save", "", "--appendonly", "yes", "--dir"])
        .arg(dir)
        .stdout(Stdio::null())
        .spawn()?;
    let url = format!("redis://127.0.0.1:{port}");
    tokio::time::sleep(Duration::from_millis(300)).await;
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/cornell_box.usda");
    let frames = 20;
    let args = ["--res", "32x32"].map(String::from).to_vec();
    let exe = PathBuf::from(env!("CARGO_BIN_EXE_tessera"));
    // Each frame as its own process, plainly and with the flags a worker adds (an exact film
    // kept for checkpoints, ALF progress lines).
    let direct = |worker_flags: &[&str]| -> anyhow::Result<f64> {
        let t = Instant::now();
        for f in 1..=frames {
            let out = Command::new(&exe)
                .arg("render")
                .arg(&scene)
                .args(["--frame", &f.to_string(), "--spp", "4"])
                .args(&args)
                .args(worker_flags)
                .arg("-o")
                .arg(dir.join(format!("direct.{f}.exr")))
                .output()?;
            anyhow::ensure!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
        }
        Ok(t.elapsed().as_secs_f64() / frames as f64)
    };
    let (plain, flagged) = (direct(&[])?, direct(&["--checkpoint-interval", "30", "--resume", "--alf-progress"])?);

    let mut conn = tessera::farm::Redis::connect(&url).await?;
    let submission = tessera::farm::queue::Submission {
        scene: scene.clone(),
        frames: (1..=frames).collect(),
        output: dir.join("farm.####.exr"),
        spp: 4,
        split: 1,
        render_args: args,
        priority: tessera::farm::DEFAULT_PRIORITY,
    };
    let job = tessera::farm::queue::submit(&mut conn, &submission).await?;
    let cfg = tessera::farm::worker::WorkerConfig {
        redis: url,
        name: "bench".into(),
        server: None,
        claim_after: Duration::from_secs(60),
        heartbeat: Duration::from_secs(20),
        checkpoint_interval: Duration::from_secs(30),
        exit_when_idle: Some(Duration::from_millis(600)),
        render_exe: exe,
    };
    tessera::farm::worker::run(&cfg).await?;
    let tasks = tessera::farm::queue::tasks(&mut conn, &job).await?;
    let ms = |t: &std::collections::BTreeMap<String, String>, k: &str| t[k].parse::<f64>().unwrap_or(0.0);
    // From the first task's start to the last one's acknowledgement (the worker's idle wait
    // before it exits is not the queue's).
    let farm = (ms(&tasks[frames as usize - 1], "finished") - ms(&tasks[0], "started")) / 1e3 / frames as f64;
    let pickup = ms(&tasks[0], "started") - ms(&tasks[0], "submitted");
    // From one task's acknowledgement to the next one's start: the queue's own share.
    let gaps: Vec<f64> = tasks.windows(2).map(|w| ms(&w[1], "started") - ms(&w[0], "finished")).collect();
    let t = Instant::now();
    tessera::farm::queue::status(&mut conn, &job).await?;
    let status = t.elapsed().as_secs_f64() * 1e3;
    println!(
        "queue, {frames} tasks of 32x32 at 4 spp: {:.0} ms per task through the farm vs {:.0} ms per direct tessera render ({:.0} ms with the worker's checkpoint and progress flags); \
         between one task's ack and the next start {:.1} ms (mean); status of a {frames}-task job {:.1} ms; first task picked up {:.0} ms after submission (worker started after it)",
        farm * 1e3,
        plain * 1e3,
        flagged * 1e3,
        gaps.iter().sum::<f64>() / gaps.len().max(1) as f64,
        status,
        pickup
    );
    redis.kill().ok();
    Ok(())
}

#[tokio::main]
async fn main() {
    let dir = std::env::temp_dir().join(format!("tessera-farm-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    checkpoint(&dir, false);
    checkpoint(&dir, true);
    merge(&dir);
    if let Err(e) = queue(&dir).await {
        println!("queue: not measured ({e:#})");
    }
    std::fs::remove_dir_all(&dir).ok();
}
