//! The queue side of `tessera farm`: submit a job, show its state, cancel it, retry what
//! failed.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};

use super::{DEAD, GROUP, PRIORITIES, Redis, job_key, slice_ranges, task_key, tasks_stream};

/// What `tessera farm submit` puts on the queue.
#[derive(Clone, Debug)]
pub struct Submission {
    /// The scene, on storage every worker reads (made absolute).
    pub scene: PathBuf,
    /// Frames to render.
    pub frames: Vec<i64>,
    /// Output pattern (`out/shot.####.exr`), on shared storage.
    pub output: PathBuf,
    /// Samples per pixel.
    pub spp: u32,
    /// Slices per frame (1: whole frames).
    pub split: u32,
    /// Further `tessera render` arguments (`--res 1920x1080 --aov albedo`).
    pub render_args: Vec<String>,
    /// 0 (lowest) to 9: workers take the highest priority's tasks first.
    pub priority: u8,
}

/// Creates every priority's stream and its consumer group unless they exist.
pub async fn ensure_groups(redis: &mut Redis) -> Result<()> {
    for p in PRIORITIES {
        let create = redis::cmd("XGROUP").arg("CREATE").arg(tasks_stream(p)).arg(GROUP).arg("0").arg("MKSTREAM").clone();
        match redis.query::<String>(&create).await {
            Err(e) if e.to_string().contains("BUSYGROUP") => {}
            other => other.map(|_| ())?,
        }
    }
    Ok(())
}

/// Puts a job on the queue: one task per frame, or per (frame, sample range) when split.
/// Returns the job id.
pub async fn submit(redis: &mut Redis, s: &Submission) -> Result<String> {
    let scene = std::path::absolute(&s.scene)?;
    let bytes = std::fs::read(&scene).with_context(|| format!("cannot read {}", scene.display()))?;
    let outputs = crate::commands::frames::frame_paths(&std::path::absolute(&s.output)?, &s.frames)?;
    if !PRIORITIES.contains(&s.priority) {
        bail!("--priority {} is outside {}..={}", s.priority, PRIORITIES.start(), PRIORITIES.end());
    }
    ensure_groups(redis).await?;
    let stream = tasks_stream(s.priority);
    let id = format!("j{}", redis.query::<u64>(redis::cmd("INCR").arg("tessera:jobs")).await?);
    let ranges = slice_ranges(s.spp, s.split.max(1));
    let tasks = s.frames.len() * ranges.len();
    redis
        .query::<()>(
            redis::cmd("HSET")
                .arg(job_key(&id))
                .arg("scene")
                .arg(scene.display().to_string())
                .arg("scene_hash")
                .arg(tessera_wire::content_hash(&bytes))
                .arg("spp")
                .arg(s.spp)
                .arg("args")
                .arg(serde_json::to_string(&s.render_args)?)
                .arg("tasks")
                .arg(tasks)
                .arg("state")
                .arg("active")
                .arg("priority")
                .arg(s.priority),
        )
        .await?;
    let mut n = 0;
    for (&frame, output) in s.frames.iter().zip(&outputs) {
        for (k, range) in ranges.iter().enumerate() {
            let slice = if ranges.len() > 1 { format!("{}-{}", range.start, range.end) } else { String::new() };
            let key = task_key(&id, n);
            let fields: [(&str, String); 9] = [
                ("stream", stream.clone()),
                ("submitted", super::now_ms()),
                ("frame", frame.to_string()),
                ("output", output.display().to_string()),
                ("slice", k.to_string()),
                ("slices", ranges.len().to_string()),
                ("range", slice),
                ("state", "queued".into()),
                ("attempts", "0".into()),
            ];
            redis.query::<()>(redis::cmd("HSET").arg(&key).arg(&fields[..])).await?;
            redis.query::<String>(redis::cmd("XADD").arg(&stream).arg("*").arg("task").arg(&key)).await?;
            n += 1;
        }
    }
    Ok(id)
}

/// Every task of job `id`, in submission order.
pub async fn tasks(redis: &mut Redis, id: &str) -> Result<Vec<BTreeMap<String, String>>> {
    let job = redis.hash(&job_key(id)).await?;
    let Some(count) = job.get("tasks").and_then(|n| n.parse::<usize>().ok()) else { bail!("no job {id} on this queue") };
    let mut out = Vec::with_capacity(count);
    for n in 0..count {
        out.push(redis.hash(&task_key(id, n)).await?.into_iter().collect());
    }
    Ok(out)
}

/// `tessera farm status`: one line per task and the job's progress.
pub async fn status(redis: &mut Redis, id: &str) -> Result<String> {
    let tasks = tasks(redis, id).await?;
    let job = redis.hash(&job_key(id)).await?;
    let field = |t: &BTreeMap<String, String>, k: &str| t.get(k).cloned().unwrap_or_default();
    let state = job.get("state").map_or("unknown", String::as_str);
    let mut out = format!("job {id} ({state}): {}\n", job.get("scene").map_or("", String::as_str));
    out += "  frame  slice      state      worker          done  attempts  note\n";
    let mut done = 0.0;
    for t in &tasks {
        let state = field(t, "state");
        let percent: f64 = field(t, "percent").parse().unwrap_or(0.0);
        done += if state == "done" { 1.0 } else { percent / 100.0 };
        let slice = if field(t, "range").is_empty() { "-".to_string() } else { field(t, "range") };
        out += &format!(
            "  {:>5}  {:<9}  {:<9}  {:<14} {:>4.0}%  {:>8}  {}\n",
            field(t, "frame"),
            slice,
            state,
            field(t, "worker"),
            if state == "done" { 100.0 } else { percent },
            field(t, "attempts"),
            field(t, "error")
        );
    }
    let count = |s: &str| tasks.iter().filter(|t| field(t, "state") == s).count();
    out += &format!(
        "{:.0}% done: {} of {} tasks done, {} rendering, {} queued, {} failed\n",
        100.0 * done / tasks.len().max(1) as f64,
        count("done"),
        tasks.len(),
        count("rendering"),
        count("queued"),
        count("failed")
    );
    Ok(out)
}

/// `tessera farm cancel`: queued tasks are dropped when a worker meets them, running ones
/// stopped at the workers' next heartbeat.
pub async fn cancel(redis: &mut Redis, id: &str) -> Result<()> {
    tasks(redis, id).await?;
    redis.query::<()>(redis::cmd("HSET").arg(job_key(id)).arg("state").arg("cancelled")).await
}

/// `tessera farm retry --failed`: failed tasks go back on the queue with fresh attempts.
/// Returns how many.
pub async fn retry_failed(redis: &mut Redis, id: &str) -> Result<usize> {
    let tasks = tasks(redis, id).await?;
    redis.query::<()>(redis::cmd("HSET").arg(job_key(id)).arg("state").arg("active")).await?;
    let mut retried = 0;
    for (n, t) in tasks.iter().enumerate() {
        if t.get("state").map(String::as_str) == Some("failed") {
            let key = task_key(id, n);
            redis.query::<()>(redis::cmd("HSET").arg(&key).arg("state").arg("queued").arg("attempts").arg(0).arg("error").arg("")).await?;
            let stream = t.get("stream").cloned().unwrap_or_else(|| tasks_stream(super::DEFAULT_PRIORITY));
            redis.query::<String>(redis::cmd("XADD").arg(stream).arg("*").arg("task").arg(&key)).await?;
            retried += 1;
        }
    }
    Ok(retried)
}

/// The dead-letter stream's entries as (task key, error), oldest first.
pub async fn dead_letters(redis: &mut Redis) -> Result<Vec<(String, String)>> {
    let entries: Vec<(String, Vec<String>)> = redis.query(redis::cmd("XRANGE").arg(DEAD).arg("-").arg("+")).await?;
    Ok(entries
        .into_iter()
        .map(|(_, fields)| {
            let get = |k: &str| fields.chunks(2).find(|p| p[0] == k).map(|p| p[1].clone()).unwrap_or_default();
            (get("task"), get("error"))
        })
        .collect())
}

/// The partial film of slice `k` of a frame's output.
pub fn slice_path(output: &Path, k: usize) -> PathBuf {
    let mut name = output.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".part{k}"));
    output.with_file_name(name)
}
