//! `tessera farm`: frames, and slices of frames' samples, as tasks on a Redis Streams
//! consumer group. Redis gives at-least-once delivery, each consumer's pending list and
//! `XAUTOCLAIM` for work whose worker went silent; Tessera's part is tasks that may run twice
//! without harm: outputs are written atomically, a frame resumes from its checkpoint, and a
//! task is acknowledged only once its output is in place.
//!
//! Keys (all under `tessera:`): the streams `tasks:0` to `tasks:9`, one per priority, each
//! with the group `workers`, whose entries name a task; `dead`, the stream of tasks that failed for good; per job the hash
//! `job:ID` (scene, its content hash, render arguments, state); per task the hash
//! `task:ID:N` (frame, sample range, output, state, worker, percent, attempts, error); per
//! split frame the set `slices:ID:FRAME` of its finished slices.

pub mod queue;
pub mod worker;

use std::collections::HashMap;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};

/// Job priorities, lowest first: each has its own stream, and workers take from the highest
/// that has work.
pub const PRIORITIES: std::ops::RangeInclusive<u8> = 0..=9;
/// The priority of a job submitted without `--priority`.
pub const DEFAULT_PRIORITY: u8 = 5;

/// The stream of tasks of one priority.
pub fn tasks_stream(priority: u8) -> String {
    format!("tessera:tasks:{priority}")
}

/// The consumer group every worker reads the task streams through.
pub const GROUP: &str = "workers";
/// The dead-letter stream: tasks that failed on every attempt, or on a bad scene.
pub const DEAD: &str = "tessera:dead";
/// Attempts a task gets before it goes to [`DEAD`].
pub const MAX_ATTEMPTS: u32 = 3;

/// The hash of job `id`.
pub fn job_key(id: &str) -> String {
    format!("tessera:job:{id}")
}

/// The hash of task `n` of job `id`.
pub fn task_key(id: &str, n: usize) -> String {
    format!("tessera:task:{id}:{n}")
}

/// The set of finished slices of a split frame.
pub fn slices_key(id: &str, frame: i64) -> String {
    format!("tessera:slices:{id}:{frame}")
}

/// `k` sample ranges that split `spp`, cut at the pass boundaries nearest to equal shares
/// (slices must start passes to merge exactly; fewer than `k` when `spp` has fewer passes).
pub fn slice_ranges(spp: u32, k: u32) -> Vec<std::ops::Range<u32>> {
    let starts: Vec<u32> = render_core::render::pass_ranges(spp).iter().map(|r| r.start).collect();
    let mut cuts: Vec<u32> = (1..k.max(1))
        .map(|i| {
            let target = u64::from(spp) * u64::from(i) / u64::from(k);
            *starts.iter().min_by_key(|&&s| (u64::from(s)).abs_diff(target)).expect("a render has a first pass")
        })
        .filter(|&c| c > 0)
        .collect();
    cuts.dedup();
    let bounds: Vec<u32> = std::iter::once(0).chain(cuts).chain(std::iter::once(spp)).collect();
    bounds.windows(2).map(|w| w[0]..w[1]).collect()
}

/// A Redis connection that reconnects: a command that fails on a broken connection is retried
/// on a new one until [`Redis::PATIENCE`] has passed (a Redis restart takes a second or two).
pub struct Redis {
    client: redis::Client,
    conn: Option<redis::aio::MultiplexedConnection>,
}

impl Redis {
    /// How long a command keeps retrying while Redis is unreachable.
    pub const PATIENCE: Duration = Duration::from_secs(60);

    /// Connects to `url` (`redis://HOST:PORT`).
    pub async fn connect(url: &str) -> Result<Redis> {
        let client = redis::Client::open(url).with_context(|| format!("{url}: not a Redis URL"))?;
        let mut r = Redis { client, conn: None };
        r.query::<String>(&redis::cmd("PING")).await.with_context(|| format!("cannot reach Redis at {url}"))?;
        Ok(r)
    }

    /// Runs `cmd`, reconnecting and retrying while the connection is what failed.
    pub async fn query<T: redis::FromRedisValue>(&mut self, cmd: &redis::Cmd) -> Result<T> {
        let deadline = Instant::now() + Self::PATIENCE;
        loop {
            let result = match &mut self.conn {
                Some(c) => cmd.query_async::<T>(c).await,
                None => match self.client.get_multiplexed_async_connection_with_config(&Self::config()).await {
                    Ok(c) => {
                        self.conn = Some(c);
                        continue;
                    }
                    Err(e) => Err(e),
                },
            };
            match result {
                Ok(v) => return Ok(v),
                Err(e) if is_connection_error(&e) && Instant::now() < deadline => {
                    tracing::warn!(error = %e, "Redis unreachable; retrying");
                    self.conn = None;
                    tokio::time::sleep(Duration::from_millis(200)).await;
                }
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// Replies may take as long as a worker's blocking read (half a second) and more; the
    /// crate's default response timeout is shorter.
    fn config() -> redis::AsyncConnectionConfig {
        redis::AsyncConnectionConfig::new()
            .set_response_timeout(Some(Duration::from_secs(10)))
            .set_connection_timeout(Some(Duration::from_secs(2)))
    }

    /// A hash's fields.
    pub async fn hash(&mut self, key: &str) -> Result<HashMap<String, String>> {
        self.query(redis::cmd("HGETALL").arg(key)).await
    }
}

/// Milliseconds since the Unix epoch, for the task timestamps.
pub fn now_ms() -> String {
    std::time::SystemTime::now().duration_since(std::time::UNIX_EPOCH).map_or(0, |d| d.as_millis()).to_string()
}

fn is_connection_error(e: &redis::RedisError) -> bool {
    e.is_io_error() || e.is_connection_refusal() || e.is_connection_dropped() || e.is_timeout() || e.is_unrecoverable_error()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slices_cut_at_pass_boundaries() {
        assert_eq!(slice_ranges(256, 4), vec![0..64, 64..128, 128..192, 192..256]);
        assert_eq!(slice_ranges(256, 1), vec![0..256]);
        // 100 spp: passes start at 0, 1, 2, 4, …, 64; 50 and 75 are nearest 32 and 64.
        assert_eq!(slice_ranges(100, 3), vec![0..32, 32..64, 64..100]);
        assert_eq!(slice_ranges(4, 8), vec![0..1, 1..2, 2..4]);
        for spp in [1, 7, 64, 300, 1024] {
            for k in 1..6 {
                let r = slice_ranges(spp, k);
                assert_eq!((r[0].start, r.last().unwrap().end), (0, spp));
                assert!(r.windows(2).all(|w| w[0].end == w[1].start && w[0].start < w[0].end));
            }
        }
    }
}
