//! Paths per second on a production-sized scene, beside Mitsuba 3 on the same USD file in the
//! same run (issue 22): `bench/production_scene.py` writes it (a 999 698-triangle terrain, 300
//! instanced glossy rocks, a textured dome), Tessera renders it on 1 and 2 threads, Mitsuba's
//! `llvm_ad_rgb` and `scalar_rgb` variants on 2, all with independent samplers at equal
//! resolution, spp and depth. Also what the renderer holds per triangle.
//! Run: `cargo bench -p tessera --bench production`.

use std::path::Path;
use std::time::Instant;

use glam::Vec3;
use render_core::camera::Camera;
use render_core::geometry::Attribute;
use render_core::integrator::IntegratorSettings;
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::sampling::SamplerKind;
use render_core::scene::{BlasCache, CommittedScene, commit};

#[path = "anchors/mod.rs"]
mod anchors;

const W: u32 = 320;
const H: u32 = 180;
const SPP: u32 = 16;
/// Mitsuba's max_depth counts vertices including the emitter: its 8 is our 7 bounces.
const MITSUBA_MAX_DEPTH: u32 = 8;

/// Seconds of the fastest of three renders on `threads` threads (seeds 0, 1, 2), the last one's
/// mean RGB, and the per-sample noise of the first two ([`anchors::relative_variance`]).
fn best_of_three(scene: &CommittedScene, threads: usize) -> (f64, Vec3, f64) {
    let settings = RenderSettings {
        width: W,
        height: H,
        spp: SPP,
        tile_size: 32,
        integrator: IntegratorSettings { max_depth: MITSUBA_MAX_DEPTH - 1, ..Default::default() },
        sampler: SamplerKind::Independent,
        ..Default::default()
    };
    let camera = Camera::new(&scene.camera("").unwrap(), W, H);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
    let (mut best, mut mean, mut images) = (f64::INFINITY, Vec3::ZERO, Vec::new());
    for seed in 0..3 {
        let t = Instant::now();
        let (fb, _) = pool.install(|| render_to_framebuffer(scene, &camera, &RenderSettings { seed, ..settings.clone() }));
        best = best.min(t.elapsed().as_secs_f64());
        let rgb: Vec<[f32; 3]> = fb.layers[&render_core::film::Aov::Beauty].chunks(4).map(|p| [p[0], p[1], p[2]]).collect();
        mean = rgb.iter().fold(Vec3::ZERO, |s, p| s + Vec3::from(*p)) / (W * H) as f32;
        images.push(rgb);
    }
    (best, mean, anchors::relative_variance(&images[0], &images[1]))
}

/// [`resident_bytes`] after handing the allocator's free memory back to the system (glibc's
/// `malloc_trim`; elsewhere as it is).
fn trimmed_resident_bytes() -> u64 {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap memory to the system.
    unsafe {
        libc::malloc_trim(0);
    }
    resident_bytes()
}

/// This process's resident memory, from /proc/self/statm (0 where there is none).
fn resident_bytes() -> u64 {
    let statm = std::fs::read_to_string("/proc/self/statm").unwrap_or_default();
    statm.split_whitespace().nth(1).and_then(|p| p.parse::<u64>().ok()).unwrap_or(0) * 4096
}

/// Bytes of a mesh's arrays as the renderer holds them.
fn mesh_bytes(m: &render_core::geometry::Mesh) -> u64 {
    fn attribute<T>(a: &Attribute<T>) -> usize {
        match a {
            Attribute::None => 0,
            Attribute::Vertex(v) | Attribute::FaceVarying(v) => std::mem::size_of_val(&v[..]),
        }
    }
    let primvars: usize = m.primvars.iter().map(|p| attribute(&p.values)).sum();
    (std::mem::size_of_val(&m.positions[..]) + std::mem::size_of_val(&m.indices[..]) + attribute(&m.normals) + attribute(&m.uvs) + primvars)
        as u64
}

fn main() {
    let out = std::env::temp_dir().join("tessera-bench-production");
    std::fs::create_dir_all(&out).unwrap();
    let usd = out.join("production.usdc");
    if !usd.exists() {
        let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/production_scene.py");
        let status = std::process::Command::new("python3").arg(script).arg(&usd).status().expect("python3 runs");
        assert!(status.success(), "bench/production_scene.py failed (pip install usd-core numpy)");
    }
    let t = Instant::now();
    let translation = tessera::usd::load(&usd).unwrap();
    let loaded = t.elapsed().as_secs_f64();
    let desc = translation.to_scene_desc();
    let before = trimmed_resident_bytes();
    let t = Instant::now();
    let scene = commit(&desc, &mut BlasCache::default()).unwrap();
    let committed = t.elapsed().as_secs_f64();
    // The commit shares the description's meshes and adds the BVHs, lights and instances: its
    // growth in resident memory plus the meshes' arrays is what the renderer holds per
    // triangle. Both readings are taken with the allocator's free memory handed back, so the
    // figure counts what the commit keeps, not which freed scratch the allocator happened to
    // reuse (that moved it by 4 bytes a triangle between two layouts of the same live data).
    let grown = trimmed_resident_bytes().saturating_sub(before);
    let triangles: u64 = desc.meshes.values().map(|m| m.mesh.indices.len() as u64).sum();
    let arrays: u64 = desc.meshes.values().map(|m| mesh_bytes(&m.mesh)).sum();
    let paths = (W * H * SPP) as f64;
    println!(
        "production: {W}x{H}, {SPP} spp, max depth {} bounces (Mitsuba max_depth {MITSUBA_MAX_DEPTH}), independent samplers",
        MITSUBA_MAX_DEPTH - 1
    );
    println!("tessera: USD read {loaded:.2} s, commit (BVHs, lights) {committed:.2} s");
    println!(
        "tessera memory: {triangles} distinct triangles; mesh arrays {:.1} MB, commit +{:.1} MB resident: {:.0} bytes per triangle",
        arrays as f64 / 1e6,
        grown as f64 / 1e6,
        (arrays + grown) as f64 / triangles as f64
    );
    best_of_three(&scene, 2); // warm caches
    let ours: Vec<(usize, (f64, Vec3, f64))> = [1, 2].into_iter().map(|threads| (threads, best_of_three(&scene, threads))).collect();
    let args = [W.to_string(), H.to_string(), SPP.to_string(), MITSUBA_MAX_DEPTH.to_string(), out.display().to_string()];
    let anchor = |variant: &str| anchors::run("production", &[&[usd.display().to_string()][..], &args, &[variant.to_string()]].concat());
    let (llvm, scalar) = (anchor("llvm_ad_rgb"), anchor("scalar_rgb"));
    println!("{:<30} {:>9} {:>10} {:>16} {:>18}", "renderer", "seconds", "Mpaths/s", "vs mitsuba llvm", "vs mitsuba scalar");
    let ratio = |s: f64, m: &Option<anchors::Timing>| m.as_ref().map_or("-".to_string(), |m| format!("{:.2}x", m.seconds / s));
    for (threads, (s, _, _)) in &ours {
        let name = format!("tessera, {threads} thread(s)");
        println!("{name:<30} {s:>9.3} {:>10.3} {:>16} {:>18}", paths / s / 1e6, ratio(*s, &llvm), ratio(*s, &scalar));
    }
    for (name, m) in [("mitsuba llvm (2 thr)", &llvm), ("mitsuba scalar (2 thr)", &scalar)] {
        if let Some(m) = m {
            println!("{name:<30} {:>9.3} {:>10.3}", m.seconds, m.paths_per_s / 1e6);
        }
    }
    // Paths per second compare like with like only if the paths are alike: the images' means
    // say whether the two scenes light and bounce alike.
    println!("mean RGB: tessera {:.4}", ours[1].1.1);
    for (name, m) in [("mitsuba llvm", &llvm), ("mitsuba scalar", &scalar)] {
        if let Some(mean) = m.as_ref().and_then(|m| m.mean.as_ref()) {
            println!("mean RGB: {name} {mean:.4?}");
        }
    }
    // Paths per second say nothing of what a path is worth: the noise each renderer leaves per
    // sample does, and noise × time is the time to equal noise.
    let (seconds, _, noise) = ours[1].1;
    println!("noise per sample (relative variance per pixel at {SPP} spp, two seeds): tessera {noise:.4}");
    for (name, m) in [("mitsuba llvm", &llvm), ("mitsuba scalar", &scalar)] {
        if let Some((m, theirs)) = m.as_ref().and_then(|m| Some((m, m.noise?))) {
            println!("  {name} {theirs:.4}: noise x time, tessera {:.2}x {name}'s", noise * seconds / (theirs * m.seconds));
        }
    }
}
