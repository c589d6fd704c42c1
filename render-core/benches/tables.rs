//! What a render waits for before its first tile while the energy tables are built: the rows
//! one material's lookups read (each built when first read), against every row of every table
//! built on one core (what a first render waited for when tables were built whole, and what a
//! server's background warm-up does). Each figure is taken once, in a fresh process: the
//! tables are process-wide. Run: `cargo bench -p render-core --bench tables`.

use std::time::Instant;

use glam::Vec3;
use render_core::bsdf::{charlie, disney, energy, microfacet::Ggx};

/// Milliseconds `f` takes.
fn millis(f: impl FnOnce()) -> f64 {
    let t = Instant::now();
    f();
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let at = energy::AnisoCoords::of(Ggx { ax: 0.3, ay: 0.1 });
    let firsts = [
        ("GGX (roughness 0.3)", millis(|| _ = energy::ggx().e(0.5, 0.3))),
        ("dielectric specular (IOR 1.5)", millis(|| _ = energy::dielectric_specular().e(1.5, 0.3, 0.5))),
        ("glass (IOR 1.5)", millis(|| _ = energy::glass().e(1.5, 0.3, 0.5) + energy::glass().e(1.0 / 1.5, 0.3, 0.5))),
        ("anisotropic GGX", millis(|| _ = energy::ggx_anisotropic().e(&at, Vec3::new(0.6, 0.0, 0.8)))),
        ("sheen (roughness 0.3)", millis(|| _ = charlie::sheen_energy().e(0.3, 0.5))),
        ("Disney diffuse scales", millis(|| _ = disney::diffuse_energy_scales(0.5, 0.0))),
    ];
    let one_material: f64 = firsts.iter().map(|(_, ms)| ms).sum();
    let whole = millis(energy::warm_up);
    println!("energy tables, first lookups of one material (rows built when first read), one thread:");
    for (name, ms) in firsts {
        println!("  {name:32} {ms:8.1} ms");
    }
    println!("  {:32} {one_material:8.1} ms", "all of the above");
    println!("every other row of every table (energy::warm_up, one core): {whole:.0} ms");
    println!("one material's rows / every row: {:.4}", one_material / (one_material + whole));
}
