//! `tessera farm worker`: takes tasks from the consumer group, renders each in a child
//! `tessera render` (checkpointing into the shared output directory, or writing a slice's
//! film), heartbeats while it runs, and acknowledges a task only once its output is in
//! place. Work whose worker went silent is claimed back with `XAUTOCLAIM` and resumes from
//! its checkpoint.

use std::collections::HashMap;
use std::path::PathBuf;
use std::process::Stdio;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use tokio::io::{AsyncBufReadExt, AsyncReadExt, BufReader};

use super::queue::{ensure_groups, slice_path};
use super::{DEAD, GROUP, MAX_ATTEMPTS, PRIORITIES, Redis, job_key, slices_key, tasks_stream};

/// How a worker runs.
#[derive(Clone, Debug)]
pub struct WorkerConfig {
    /// `redis://HOST:PORT`.
    pub redis: String,
    /// The consumer name (unique per worker).
    pub name: String,
    /// Render server URL; `None`: each task starts an embedded one.
    pub server: Option<String>,
    /// A task whose worker has not heartbeaten for this long is claimed by another.
    pub claim_after: Duration,
    /// Time between heartbeats (well under `claim_after`).
    pub heartbeat: Duration,
    /// Time between a frame's checkpoints.
    pub checkpoint_interval: Duration,
    /// Exit once no task has come for this long (`None`: run until killed).
    pub exit_when_idle: Option<Duration>,
    /// The `tessera` executable that renders each task (the worker's own, normally).
    pub render_exe: PathBuf,
}

/// What a worker did before it exited.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct WorkerSummary {
    /// Tasks finished and acknowledged.
    pub done: u32,
    /// Tasks sent to the dead-letter stream.
    pub failed: u32,
}

/// How one task's render ended.
enum Outcome {
    Done,
    /// The scene or settings are bad: retrying will not help.
    BadInput(String),
    /// May work on another attempt.
    Transient(String),
    Cancelled,
}

/// Runs tasks until idle for `exit_when_idle`, or forever.
pub async fn run(cfg: &WorkerConfig) -> Result<WorkerSummary> {
    let mut redis = Redis::connect(&cfg.redis).await?;
    ensure_groups(&mut redis).await?;
    let span = tracing::info_span!("worker", name = %cfg.name);
    let _entered = span.enter();
    let mut summary = WorkerSummary::default();
    let mut idle_since = Instant::now();
    loop {
        let next = match claim_stale(&mut redis, cfg).await? {
            Some(t) => Some(t),
            None => read_new(&mut redis, cfg).await?,
        };
        let Some(delivery) = next else {
            if cfg.exit_when_idle.is_some_and(|d| idle_since.elapsed() >= d) {
                return Ok(summary);
            }
            tokio::time::sleep(IDLE_POLL).await;
            continue;
        };
        match handle(&mut redis, cfg, &delivery).await? {
            Some(true) => summary.done += 1,
            Some(false) => summary.failed += 1,
            None => {}
        }
        idle_since = Instant::now();
    }
}

/// How long an idle worker waits before it looks at the queue again. A blocking read cannot
/// wait on the priorities in order, so idle workers poll: 10 cheap commands per poll.
const IDLE_POLL: Duration = Duration::from_millis(250);

/// A stream entry: its id and its fields as a flat name, value list.
type Entry = (String, Vec<String>);

/// One delivery of a task: the stream and entry that carried it, and the task's hash key.
struct Delivery {
    stream: String,
    id: String,
    key: String,
}

/// A task another worker left silent for `claim_after`, now ours: the highest priority's.
async fn claim_stale(redis: &mut Redis, cfg: &WorkerConfig) -> Result<Option<Delivery>> {
    let ms = cfg.claim_after.as_millis() as u64;
    for p in PRIORITIES.rev() {
        let stream = tasks_stream(p);
        let cmd = redis::cmd("XAUTOCLAIM").arg(&stream).arg(GROUP).arg(&cfg.name).arg(ms).arg("0-0").arg("COUNT").arg(1).clone();
        // Redis 7: (next cursor, claimed entries, ids deleted meanwhile).
        let (_, entries, _): (String, Vec<Entry>, Vec<String>) = redis.query(&cmd).await?;
        if let Some(d) = entries.into_iter().next().and_then(|e| delivery(&stream, e)) {
            return Ok(Some(d));
        }
    }
    Ok(None)
}

/// The next new task of the highest priority that has one.
async fn read_new(redis: &mut Redis, cfg: &WorkerConfig) -> Result<Option<Delivery>> {
    for p in PRIORITIES.rev() {
        let stream = tasks_stream(p);
        let cmd = redis::cmd("XREADGROUP")
            .arg("GROUP")
            .arg(GROUP)
            .arg(&cfg.name)
            .arg("COUNT")
            .arg(1)
            .arg("STREAMS")
            .arg(&stream)
            .arg(">")
            .clone();
        let reply: Option<Vec<(String, Vec<Entry>)>> = redis.query(&cmd).await?;
        if let Some(d) = reply.into_iter().flatten().flat_map(|(_, entries)| entries).next().and_then(|e| delivery(&stream, e)) {
            return Ok(Some(d));
        }
    }
    Ok(None)
}

fn delivery(stream: &str, (id, fields): Entry) -> Option<Delivery> {
    let key = fields.chunks(2).find(|p| p.len() == 2 && p[0] == "task").map(|p| p[1].clone())?;
    Some(Delivery { stream: stream.to_string(), id, key })
}

/// Runs one delivery of task `key` (stream entry `id`): `Some(true)` done, `Some(false)`
/// dead-lettered, `None` neither (cancelled, or left pending for another attempt).
async fn handle(redis: &mut Redis, cfg: &WorkerConfig, d: &Delivery) -> Result<Option<bool>> {
    let key = d.key.as_str();
    let task = redis.hash(key).await?;
    let job_id = job_of(key);
    let job = redis.hash(&job_key(&job_id)).await?;
    let field = |m: &HashMap<String, String>, k: &str| m.get(k).cloned().unwrap_or_default();
    if task.is_empty() || job.is_empty() || field(&task, "state") == "done" {
        ack(redis, d).await?;
        return Ok(None);
    }
    if field(&job, "state") == "cancelled" {
        set(redis, key, &[("state", "cancelled")]).await?;
        ack(redis, d).await?;
        return Ok(None);
    }
    let attempts: u32 = redis.query(redis::cmd("HINCRBY").arg(key).arg("attempts").arg(1)).await?;
    if attempts > MAX_ATTEMPTS {
        let why = format!("gave up after {MAX_ATTEMPTS} attempts: {}", field(&task, "error"));
        return dead_letter(redis, d, &why).await.map(Some);
    }
    if let Some(why) = scene_problem(&job) {
        return dead_letter(redis, d, &why).await.map(Some);
    }
    let _span = tracing::info_span!("task", key, frame = %field(&task, "frame"), attempt = attempts).entered();
    set(redis, key, &[("state", "rendering"), ("worker", &cfg.name), ("percent", "0"), ("started", &super::now_ms())]).await?;
    match render_task(redis, cfg, d, &job, &task).await? {
        Outcome::Done => {
            if field(&task, "slices").parse::<u32>().unwrap_or(1) > 1
                && let Err(why) = merge_when_complete(redis, &job_id, &job, &task).await?
            {
                set(redis, key, &[("state", "queued"), ("error", &why)]).await?;
                return Ok(None);
            }
            set(redis, key, &[("state", "done"), ("percent", "100"), ("error", ""), ("finished", &super::now_ms())]).await?;
            ack(redis, d).await?;
            Ok(Some(true))
        }
        Outcome::BadInput(why) => dead_letter(redis, d, &why).await.map(Some),
        Outcome::Cancelled => {
            set(redis, key, &[("state", "cancelled")]).await?;
            ack(redis, d).await?;
            Ok(None)
        }
        Outcome::Transient(why) => {
            // Left pending: claimed again once idle for claim_after, by any worker.
            set(redis, key, &[("state", "queued"), ("error", &why)]).await?;
            Ok(None)
        }
    }
}

/// Why the job's scene cannot be rendered: gone, or changed since submission.
fn scene_problem(job: &HashMap<String, String>) -> Option<String> {
    let scene = job.get("scene").map_or("", String::as_str);
    match std::fs::read(scene) {
        Err(e) => Some(format!("cannot read the scene {scene}: {e}")),
        Ok(bytes) if Some(&tessera_wire::content_hash(&bytes)) != job.get("scene_hash") => {
            Some(format!("the scene {scene} changed after the job was submitted; submit it again"))
        }
        Ok(_) => None,
    }
}

/// The `tessera render` a task runs.
fn render_command(cfg: &WorkerConfig, job: &HashMap<String, String>, task: &HashMap<String, String>) -> Result<tokio::process::Command> {
    let field = |m: &HashMap<String, String>, k: &str| m.get(k).cloned().unwrap_or_default();
    let args: Vec<String> = serde_json::from_str(&field(job, "args")).context("the job's render arguments")?;
    let mut cmd = tokio::process::Command::new(&cfg.render_exe);
    cmd.arg("render").arg(field(job, "scene")).args(["--frame", &field(task, "frame"), "--spp", &field(job, "spp"), "--alf-progress"]);
    cmd.args(args);
    if let Some(server) = &cfg.server {
        cmd.args(["--server", server]);
    }
    let output = PathBuf::from(field(task, "output"));
    match field(task, "range") {
        r if r.is_empty() => {
            cmd.arg("-o").arg(&output).arg("--resume");
            cmd.args(["--checkpoint-interval", &cfg.checkpoint_interval.as_secs_f64().to_string()]);
        }
        r => {
            let k: usize = field(task, "slice").parse().unwrap_or(0);
            cmd.args(["--sample-range", &r, "--partial"]).arg(slice_path(&output, k));
        }
    }
    cmd.stdout(Stdio::piped()).stderr(Stdio::piped()).stdin(Stdio::null()).kill_on_drop(true);
    // SAFETY: prctl is async-signal-safe; it only asks the kernel to kill the child when this
    // worker dies, so a killed worker leaves no render running that nobody will acknowledge.
    unsafe {
        cmd.pre_exec(|| {
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL);
            Ok(())
        });
    }
    Ok(cmd)
}

/// Renders a task in a child process, heartbeating and recording its progress.
async fn render_task(
    redis: &mut Redis,
    cfg: &WorkerConfig,
    d: &Delivery,
    job: &HashMap<String, String>,
    task: &HashMap<String, String>,
) -> Result<Outcome> {
    let mut child = render_command(cfg, job, task)?.spawn().context("cannot start tessera render")?;
    let mut lines = BufReader::new(child.stdout.take().expect("piped")).lines();
    let mut stderr = child.stderr.take().expect("piped");
    let errors = tokio::spawn(async move {
        let mut text = String::new();
        stderr.read_to_string(&mut text).await.ok();
        text
    });
    let mut beat = tokio::time::interval(cfg.heartbeat);
    let mut reading = true;
    let status = loop {
        tokio::select! {
            line = lines.next_line(), if reading => match line {
                Ok(Some(l)) => {
                    if let Some(p) = l.strip_prefix("ALF_PROGRESS ").and_then(|p| p.strip_suffix('%')) {
                        set(redis, &d.key, &[("percent", p)]).await?;
                    }
                }
                _ => reading = false,
            },
            _ = beat.tick() => {
                // Resets the entry's idle time: the task is still ours.
                redis.query::<redis::Value>(redis::cmd("XCLAIM").arg(&d.stream).arg(GROUP).arg(&cfg.name).arg(0).arg(&d.id).arg("JUSTID")).await?;
                if redis.hash(&job_key(&job_of(&d.key))).await?.get("state").map(String::as_str) == Some("cancelled") {
                    child.kill().await.ok();
                    return Ok(Outcome::Cancelled);
                }
            }
            status = child.wait() => break status?,
        }
    };
    let stderr = errors.await.unwrap_or_default();
    let why = || stderr.lines().filter(|l| l.starts_with("error")).collect::<Vec<_>>().join("; ");
    Ok(match status.code() {
        Some(0) => Outcome::Done,
        Some(crate::exit::BAD_INPUT) => Outcome::BadInput(why()),
        code => Outcome::Transient(format!("tessera render exited with {code:?}: {}", why())),
    })
}

/// The job id in a task's key (`tessera:task:ID:N`).
fn job_of(task_key: &str) -> String {
    task_key.trim_start_matches("tessera:task:").rsplit_once(':').map_or("", |(j, _)| j).to_string()
}

/// After a slice: when every slice of the frame is in, merges them into the frame's EXR and
/// removes them. Two workers finishing the last slices together may both merge: the merges
/// write the same bytes atomically, and one that finds a slice already removed succeeds when
/// the frame is complete at its path. `Err` with the reason when the frame is not merged
/// (the task is then left for another attempt).
async fn merge_when_complete(
    redis: &mut Redis,
    job_id: &str,
    job: &HashMap<String, String>,
    task: &HashMap<String, String>,
) -> Result<std::result::Result<(), String>> {
    let spp = job.get("spp").map_or("", String::as_str);
    // Denoised once, after the merge (never slice by slice).
    let denoise = job.get("args").is_some_and(|a| a.contains("\"--denoise\""));
    let field = |k: &str| task.get(k).cloned().unwrap_or_default();
    let frame: i64 = field("frame").parse().unwrap_or(0);
    let slices: usize = field("slices").parse().unwrap_or(1);
    let set_key = slices_key(job_id, frame);
    redis.query::<()>(redis::cmd("SADD").arg(&set_key).arg(field("slice"))).await?;
    if redis.query::<usize>(redis::cmd("SCARD").arg(&set_key)).await? < slices {
        return Ok(Ok(()));
    }
    let output = PathBuf::from(field("output"));
    let complete = |o: &PathBuf| crate::output::exr_attribute(o, "sppAsked").as_deref() == Some(spp);
    if complete(&output) {
        return Ok(Ok(()));
    }
    let parts: Vec<PathBuf> = (0..slices).map(|k| slice_path(&output, k)).collect();
    let merged = tokio::task::spawn_blocking({
        let (parts, output) = (parts.clone(), output.clone());
        move || crate::commands::render::merge(&parts, &output, denoise)
    })
    .await?;
    match merged {
        Ok(_) => {
            for p in parts {
                std::fs::remove_file(p).ok();
            }
            Ok(Ok(()))
        }
        Err(_) if complete(&output) => Ok(Ok(())),
        Err(e) => Ok(Err(format!("merging frame {frame}: {e:#}"))),
    }
}

/// Sends a task to the dead-letter stream with its error, marks it failed and acknowledges it.
async fn dead_letter(redis: &mut Redis, d: &Delivery, why: &str) -> Result<bool> {
    let key = d.key.as_str();
    tracing::warn!(task = key, error = why, "task failed for good");
    redis.query::<String>(redis::cmd("XADD").arg(DEAD).arg("*").arg("task").arg(key).arg("error").arg(why)).await?;
    set(redis, key, &[("state", "failed"), ("error", why)]).await?;
    ack(redis, d).await?;
    Ok(false)
}

async fn set(redis: &mut Redis, key: &str, fields: &[(&str, &str)]) -> Result<()> {
    redis.query(redis::cmd("HSET").arg(key).arg(fields)).await
}

async fn ack(redis: &mut Redis, d: &Delivery) -> Result<()> {
    redis.query::<()>(redis::cmd("XACK").arg(&d.stream).arg(GROUP).arg(&d.id)).await
}
