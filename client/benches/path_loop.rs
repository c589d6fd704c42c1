//! What the specialised path loop buys: each fixture rendered in-process on 2 threads,
//! alternating the specialised and the general loop (same seed, so the same image to the bit),
//! five times each; prints the medians and their ratio. The effects bench renders each once,
//! which this VM's timing noise (±10-25%) swamps.
//! Run: `cargo bench -p tessera --bench path_loop`.

use std::path::Path;
use std::time::Instant;

use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::integrator::{IntegratorSettings, needs_full_loop};
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, CommittedScene, commit};

const FIXTURES: &[&str] = &["cornell_box.usda", "materials/showcase.usda", "hard/many_lights.usdc", "textures/checker_plane.usda"];
const SIZE: u32 = 128;
const SPP: u32 = 32;
const RUNS: usize = 5;

fn render(scene: &CommittedScene, general_loop: bool) -> (Vec<f32>, f64) {
    let settings = RenderSettings {
        width: SIZE,
        height: SIZE,
        spp: SPP,
        seed: 1,
        tile_size: 16,
        integrator: IntegratorSettings { max_depth: 8, general_loop, ..Default::default() },
        ..Default::default()
    };
    let camera = Camera::new(&scene.camera("").unwrap(), SIZE, SIZE);
    scene.prepare_bsdfs(true);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let t = Instant::now();
    let (fb, _) = pool.install(|| render_to_framebuffer(scene, &camera, &settings));
    (fb.layers[&Aov::Beauty].clone(), t.elapsed().as_secs_f64())
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let fixtures = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures");
    println!("{SIZE}x{SIZE}, {SPP} spp, max depth 8, 2 threads, median of {RUNS} alternating runs");
    println!("{:<32} {:>12} {:>12} {:>12} {:>8}", "fixture", "loop", "special. s", "general s", "ratio");
    for name in FIXTURES {
        let translation = tessera::usd::load(&fixtures.join(name)).unwrap();
        let scene = commit(&translation.to_scene_desc(), &mut BlasCache::default()).unwrap();
        let specialised = !needs_full_loop(scene.plan.features, &IntegratorSettings::default());
        render(&scene, false); // warm caches and tables
        let (mut fast, mut general) = (Vec::new(), Vec::new());
        for _ in 0..RUNS {
            let (a, ta) = render(&scene, false);
            let (b, tb) = render(&scene, true);
            assert!(a == b, "{name}: the general loop changed the image");
            fast.push(ta);
            general.push(tb);
        }
        let (f, g) = (median(fast), median(general));
        println!("{:<32} {:>12} {:>12.3} {:>12.3} {:>7.3}x", name, if specialised { "specialised" } else { "general" }, f, g, g / f);
    }
}
