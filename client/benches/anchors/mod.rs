//! Running `bench/anchors.py`, the anchors the benches compare against in the same run
//! (Mitsuba 3, Embree), and reading its answer: one JSON object on its last line.

use std::path::Path;

/// What one anchor render took.
pub struct Timing {
    pub seconds: f64,
    pub paths_per_s: f64,
    /// The image's mean RGB, when the workload reports it (not every bench reads it).
    #[allow(dead_code)]
    pub mean: Option<Vec<f64>>,
}

/// `python3 bench/anchors.py WORKLOAD ARGS...`; `None`, said on stderr, when it fails (the
/// anchors are optional: pip install mitsuba usd-core; apt install libllvm19).
pub fn run(workload: &str, args: &[String]) -> Option<Timing> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/anchors.py");
    let o = std::process::Command::new("python3").arg(script).arg(workload).args(args).output().ok()?;
    if !o.status.success() {
        eprintln!(
            "anchor {workload} {args:?} failed (pip install mitsuba usd-core; apt install libllvm19): {}",
            String::from_utf8_lossy(&o.stderr).lines().last().unwrap_or("")
        );
        return None;
    }
    let line = String::from_utf8_lossy(&o.stdout).lines().last()?.to_string();
    let num = |k: &str| -> Option<f64> { line.split(&format!("\"{k}\": ")).nth(1)?.split([',', '}']).next()?.parse().ok() };
    let mean =
        line.split("\"mean\": [").nth(1).and_then(|s| s.split(']').next()).map(|s| s.split(", ").filter_map(|x| x.parse().ok()).collect());
    Some(Timing { seconds: num("seconds")?, paths_per_s: num("paths_per_s")?, mean })
}
