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
    /// Per-sample noise, when the workload reports it: [`relative_variance`] of two renders
    /// by different seeds.
    #[allow(dead_code)]
    pub noise: Option<f64>,
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
    Some(Timing { seconds: num("seconds")?, paths_per_s: num("paths_per_s")?, mean, noise: num("noise") })
}

/// The mean over pixels of each channel's variance between two independent renders (half their
/// squared difference), relative to the squared mean value (floored at 0.1, so dark pixels do not
/// dominate): `bench/anchors.py`'s `relative_variance`, the same formula on both sides. At equal
/// spp, the ratio of two renderers' figures is the ratio of their variances per sample.
#[allow(dead_code)]
pub fn relative_variance(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let sum: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(p, q)| (0..3).map(move |c| (p[c] as f64, q[c] as f64)))
        .map(|(x, y)| {
            let m = 0.5 * (x + y);
            0.5 * (x - y).powi(2) / (m * m + 0.01)
        })
        .sum();
    sum / (3 * a.len().max(1)) as f64
}
