//! Paths per second on the Cornell box fixture, 1 and 2 threads, beside Mitsuba 3 rendering
//! the same scene (read from the same USD file) at equal resolution, spp and depth, in the
//! same run (its LLVM variant also held to eight-lane AVX2, the vector width our builds use);
//! then error against a shared high-spp Mitsuba reference at equal spp, like with
//! like: Tessera's Sobol against Mitsuba's `multijitter` (both stratified), independent
//! against independent, and error × time for each pair on the same threads.
//! Run: `cargo bench -p tessera --bench cornell`. Environment: `REF_SPP` (default 1024, 0 to
//! skip the reference).

use std::path::Path;
use std::time::Instant;

use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::integrator::IntegratorSettings;
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::sampling::SamplerKind;
use render_core::scene::{BlasCache, CommittedScene, commit};

#[path = "anchors/mod.rs"]
mod anchors;

const W: u32 = 256;
const H: u32 = 256;
const SPP: u32 = 64;
/// Mitsuba's max_depth counts vertices including the emitter: its 8 is our 7 bounces.
const MITSUBA_MAX_DEPTH: u32 = 8;

fn render_rgb(scene: &CommittedScene, threads: usize, spp: u32, seed: u64) -> (Vec<f32>, f64) {
    render_rgb_with(scene, threads, spp, seed, SamplerKind::Sobol)
}

fn render_rgb_with(scene: &CommittedScene, threads: usize, spp: u32, seed: u64, sampler: SamplerKind) -> (Vec<f32>, f64) {
    let settings = RenderSettings {
        width: W,
        height: H,
        spp,
        seed,
        tile_size: 32,
        integrator: IntegratorSettings { max_depth: MITSUBA_MAX_DEPTH - 1, ..Default::default() },
        sampler,
        ..Default::default()
    };
    let cam = Camera::new(&scene.camera("").unwrap(), W, H);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let t = Instant::now();
    let (fb, _) = pool.install(|| render_to_framebuffer(scene, &cam, &settings));
    let secs = t.elapsed().as_secs_f64();
    let rgb = fb.layers[&Aov::Beauty].chunks(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    (rgb, secs)
}

/// Relative MSE (Rousselle et al.'s ε = 0.01 in the denominator), and mean per channel.
fn rel_mse(img: &[f32], reference: &[f32]) -> f64 {
    img.iter().zip(reference).map(|(&a, &r)| ((a - r) as f64).powi(2) / ((r as f64).powi(2) + 0.01)).sum::<f64>() / img.len() as f64
}

fn mean(img: &[f32]) -> [f64; 3] {
    let mut m = [0.0; 3];
    for p in img.chunks(3) {
        for c in 0..3 {
            m[c] += p[c] as f64;
        }
    }
    m.map(|v| v / (img.len() / 3) as f64)
}

fn read_f32(path: &Path) -> Option<Vec<f32>> {
    let bytes = std::fs::read(path).ok()?;
    Some(bytes.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect())
}

/// One Mitsuba run: (seconds, paths/s), its 64-spp image written to `out`.
fn mitsuba(usd: &Path, out: &Path, variant: &str, ref_spp: u32, sampler: &str) -> Option<(f64, f64)> {
    let args = [
        usd.to_str()?,
        &W.to_string(),
        &H.to_string(),
        &SPP.to_string(),
        &MITSUBA_MAX_DEPTH.to_string(),
        &ref_spp.to_string(),
        out.to_str()?,
        variant,
        sampler,
    ];
    let t = anchors::run("cornell", &args.map(str::to_string))?;
    Some((t.seconds, t.paths_per_s))
}

/// Best of three renders on `threads` threads: (seconds, the last image).
fn best_of_three(scene: &CommittedScene, threads: usize, sampler: SamplerKind) -> (f64, Vec<f32>) {
    let runs: Vec<(Vec<f32>, f64)> = (0..3).map(|s| render_rgb_with(scene, threads, SPP, s, sampler)).collect();
    let best = runs.iter().map(|r| r.1).fold(f64::INFINITY, f64::min);
    (best, runs.into_iter().last().unwrap().0)
}

fn main() {
    let ref_spp: u32 = std::env::var("REF_SPP").ok().and_then(|s| s.parse().ok()).unwrap_or(1024);
    let usd = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/cornell_box.usda").canonicalize().unwrap();
    let translation = tessera::usd::load(&usd).unwrap();
    let scene = commit(&translation.to_scene_desc(), &mut BlasCache::default()).unwrap();
    let paths = (W * H * SPP) as f64;

    println!("cornell: {W}x{H}, {SPP} spp, max depth {} bounces (Mitsuba max_depth {MITSUBA_MAX_DEPTH})", MITSUBA_MAX_DEPTH - 1);
    render_rgb(&scene, 2, 1, 99); // warm caches
    let ours: Vec<(usize, f64)> =
        [1, 2].into_iter().map(|threads| (threads, best_of_three(&scene, threads, SamplerKind::Sobol).0)).collect();
    let out = std::env::temp_dir().join("tessera-bench-cornell");
    std::fs::create_dir_all(&out).unwrap();
    let scalar = mitsuba(&usd, &out, "scalar_rgb", 0, "independent");
    let llvm = mitsuba(&usd, &out, "llvm_ad_rgb", ref_spp, "independent");
    let llvm_mj = mitsuba(&usd, &out, "llvm_ad_rgb", 0, "multijitter");
    // Like with like: Mitsuba's JIT runs sixteen lanes where the host has AVX-512, while our
    // x86-64-v3 builds run eight-lane AVX2 on every machine; this run holds it to AVX2.
    let llvm_avx2 = mitsuba(&usd, &out, "llvm_ad_rgb:avx2", 0, "independent");

    println!(
        "{:<30} {:>9} {:>13} {:>15} {:>15} {:>17}",
        "renderer", "seconds", "Mpaths/s", "vs mitsuba llvm", "vs llvm on avx2", "vs mitsuba scalar"
    );
    let ratio = |a: Option<(f64, f64)>, ours: f64| a.map_or("-".to_string(), |(_, p)| format!("{:.2}x", ours / p));
    for &(threads, secs) in &ours {
        let pps = paths / secs;
        let name = format!("tessera sobol, {threads} thread(s)");
        println!(
            "{:<30} {:>9.3} {:>13.3} {:>15} {:>15} {:>17}",
            name,
            secs,
            pps / 1e6,
            ratio(llvm, pps),
            ratio(llvm_avx2, pps),
            ratio(scalar, pps)
        );
    }
    for (name, r) in [
        ("mitsuba llvm indep. (2 thr)", llvm),
        ("mitsuba llvm multijit. (2 thr)", llvm_mj),
        ("mitsuba llvm avx2 ind. (2 thr)", llvm_avx2),
        ("mitsuba scalar indep. (2 thr)", scalar),
    ] {
        if let Some((s, p)) = r {
            println!("{:<30} {:>9.3} {:>13.3}", name, s, p / 1e6);
        }
    }
    if ref_spp > 0 {
        let mitsuba_runs = [("independent", llvm), ("multijitter", llvm_mj)];
        equal_error(&scene, &out, ref_spp, ours[1].1, &mitsuba_runs);
    }
}

/// Equal-spp error against Mitsuba's high-spp reference, like with like (stratified against
/// stratified, independent against independent), with error × time on 2 threads: the figure
/// that decides how long a clean image takes.
fn equal_error(scene: &CommittedScene, out: &Path, ref_spp: u32, sobol_secs: f64, mitsuba_runs: &[(&str, Option<(f64, f64)>)]) {
    let Some(reference) = read_f32(&out.join("mitsuba_ref.bin")).filter(|r| r.len() == (W * H * 3) as usize) else { return };
    let (img, _) = render_rgb(scene, 2, SPP, 7);
    let (indep_secs, indep) = best_of_three(scene, 2, SamplerKind::Independent);
    let ours = [("sobol", rel_mse(&img, &reference), sobol_secs), ("independent", rel_mse(&indep, &reference), indep_secs)];
    let theirs: Vec<(&str, f64, f64)> = mitsuba_runs
        .iter()
        .filter_map(|&(sampler, run)| Some((sampler, rel_mse(&read_f32(&out.join(format!("mitsuba_{sampler}.bin")))?, &reference), run?.0)))
        .collect();
    println!("error vs Mitsuba LLVM {ref_spp}-spp reference (relMSE at equal {SPP} spp, 2 threads), like with like:");
    for ((ours_name, e, t), their_name) in ours.iter().zip(["multijitter", "independent"]) {
        let Some(&(_, me, mt)) = theirs.iter().find(|r| r.0 == their_name) else { continue };
        println!(
            "  tessera {ours_name:<12} relMSE {e:.5} in {t:.3} s | mitsuba llvm {their_name:<12} relMSE {me:.5} in {mt:.3} s | error x time: tessera {:.2}x mitsuba's",
            (e * t) / (me * mt)
        );
    }
    let (our_ref, ref_secs) = render_rgb(scene, 2, ref_spp, 11);
    let (a, b) = (mean(&our_ref), mean(&reference));
    println!(
        "agreement at {ref_spp} spp ({ref_secs:.1} s): image means tessera [{:.4}, {:.4}, {:.4}] vs mitsuba [{:.4}, {:.4}, {:.4}]; relMSE between them {:.5}",
        a[0],
        a[1],
        a[2],
        b[0],
        b[1],
        b[2],
        rel_mse(&our_ref, &reference)
    );
}
