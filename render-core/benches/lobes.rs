//! Nanoseconds per `eval` and per `sample` for each lobe and for the principled BSDF, with
//! energy compensation on and off, on a fixed set of directions (the tables are built before
//! timing), eval and pdf as one call (`eval_pdf`, what next-event estimation asks), and per
//! path vertex (eval, pdf and a sample at one view, with the view's table lookups repeated or
//! prepared once); then what next-event estimation's light sampling costs
//! a vertex, per light shape and for sets of many lights through the light tree. Run:
//! `cargo bench -p render-core --bench lobes`.

use std::hint::black_box;
use std::time::Instant;

use glam::{Affine3A, Quat, Vec2, Vec3};
use render_core::bsdf::{Bsdf, Clearcoat, Dielectric, DisneyDiffuse, GgxReflection, Lambert, Lobe, Sheen, SpecularFresnel};
use render_core::light::{LightDesc, LightKind, LightSet, ShadingContext};
use render_core::material::Principled;
use render_core::sampling::{Pcg32, cosine_hemisphere, uniform_sphere};

const N: usize = 1 << 18;

fn inputs() -> Vec<(Vec3, Vec3, f32, Vec2)> {
    let mut rng = Pcg32::new(1, 2);
    (0..N)
        .map(|_| {
            let wo = cosine_hemisphere(rng.next_2d());
            let wi = uniform_sphere(rng.next_2d());
            (wo, wi, rng.next_f32(), rng.next_2d())
        })
        .collect()
}

fn time(f: impl Fn() -> f32) -> f64 {
    let mut best = f64::INFINITY;
    for _ in 0..5 {
        let t = Instant::now();
        black_box(f());
        best = best.min(t.elapsed().as_secs_f64());
    }
    best * 1e9 / N as f64
}

/// What a path vertex asks of its BSDF at one view: next-event estimation's eval and pdf,
/// then a sample (whose weight evaluates again).
fn vertex_work(f: impl Fn(Vec3, Vec3) -> f32, sample: impl Fn(Vec3, f32, Vec2) -> f32, (wo, wi, uc, u): &(Vec3, Vec3, f32, Vec2)) -> f32 {
    f(*wo, *wi) + sample(*wo, *uc, *u)
}

/// Nanoseconds per (f, pdf) pair asked for with two calls (`apart`) and with one (`together`).
fn pair_times(
    data: &[(Vec3, Vec3, f32, Vec2)],
    apart: impl Fn(Vec3, Vec3) -> (Vec3, f32),
    together: impl Fn(Vec3, Vec3) -> (Vec3, f32),
) -> (f64, f64) {
    let ns = |f: &dyn Fn(Vec3, Vec3) -> (Vec3, f32)| {
        time(|| {
            data.iter()
                .map(|(wo, wi, _, _)| {
                    let (v, pdf) = f(*wo, *wi);
                    v.x + pdf
                })
                .sum()
        })
    };
    (ns(&apart), ns(&together))
}

fn lobe_row(name: &str, lobe: &Lobe, data: &[(Vec3, Vec3, f32, Vec2)]) {
    let (eval, together) = pair_times(data, |wo, wi| (lobe.eval(wo, wi), lobe.pdf(wo, wi)), |wo, wi| lobe.eval_pdf(wo, wi));
    let sample = time(|| data.iter().filter_map(|(wo, _, uc, u)| lobe.sample(*wo, *uc, *u)).map(|s| s.weight.x).sum());
    // One vertex with the view's table lookups repeated (as before `Lobe::prepare`), and with
    // them made once by `prepare`: the same values, the second cheaper.
    let vertex = |prepared: bool| {
        time(|| {
            data.iter()
                .map(|d| {
                    let mut l = *lobe;
                    if prepared {
                        l.prepare(d.0);
                    }
                    let f = |wo, wi| l.eval(wo, wi).x + l.pdf(wo, wi);
                    vertex_work(f, |wo, uc, u| l.sample(wo, uc, u).map_or(0.0, |s| s.weight.x), d)
                })
                .sum()
        })
    };
    let (repeated, prepared) = (vertex(false), vertex(true));
    println!("{name:<44} {eval:>10.1} {together:>10.1} {sample:>10.1} {repeated:>10.1} {prepared:>10.1}");
}

fn bsdf_row(name: &str, bsdf: &Bsdf, data: &[(Vec3, Vec3, f32, Vec2)]) {
    let (eval, together) = pair_times(data, |wo, wi| (bsdf.eval(wo, wi), bsdf.pdf(wo, wi)), |wo, wi| bsdf.eval_pdf(wo, wi));
    let sample = time(|| {
        data.iter()
            .filter_map(|(wo, _, uc, u)| {
                let mut b = bsdf.clone();
                b.prepare(*wo);
                b.sample(*wo, *uc, *u)
            })
            .map(|s| s.weight.x)
            .sum()
    });
    let vertex = time(|| {
        data.iter()
            .map(|d| {
                let mut b = bsdf.clone();
                b.prepare(d.0);
                let f = |wo, wi| b.eval(wo, wi).x + b.pdf(wo, wi);
                vertex_work(f, |wo, uc, u| b.sample(wo, uc, u).map_or(0.0, |s| s.weight.x), d)
            })
            .sum()
    });
    println!("{name:<44} {eval:>10.1} {together:>10.1} {sample:>10.1} {:>10} {vertex:>10.1}", "");
}

/// Shading points in a 10-unit box below the lights (on their lit side), facing random ways,
/// with the numbers a light sample draws.
fn shading_points() -> Vec<(ShadingContext, f32, Vec2)> {
    let mut rng = Pcg32::new(5, 6);
    (0..N)
        .map(|_| {
            let p = (Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) - 0.5) * 10.0 - Vec3::Y * 5.0;
            let ctx = ShadingContext { p, n: uniform_sphere(rng.next_2d()), both_sides: false, time: 0.5 };
            (ctx, rng.next_f32(), rng.next_2d())
        })
        .collect()
}

/// A light of `kind` at the origin (plus `offset`), turned to face down a little askew.
fn light_at(kind: LightKind, offset: Vec3) -> render_core::light::Light {
    let xf = Affine3A::from_rotation_translation(Quat::from_rotation_x(-1.4), offset);
    LightDesc::new(kind, xf, 10.0).commit().expect("a light that emits")
}

/// Nanoseconds per `LightSet::sample_each` (every sample the walk yields, split budget
/// `budget`), and the samples yielded per call.
fn light_row(name: &str, set: &LightSet, budget: usize, points: &[(ShadingContext, f32, Vec2)]) {
    let ns = time(|| {
        let mut sum = 0.0;
        for (ctx, u_sel, u) in points {
            set.sample_each(ctx, *u_sel, *u, budget, 0, |_| true, |s, _, _| sum += s.pdf.min(1e6));
        }
        sum
    });
    let mut samples = 0usize;
    points.iter().for_each(|(ctx, u_sel, u)| set.sample_each(ctx, *u_sel, *u, budget, 0, |_| true, |_, _, _| samples += 1));
    println!("{name:<44} {ns:>10.1} {:>10.2}", samples as f64 / points.len() as f64);
}

fn light_table() {
    let points = shading_points();
    println!("{:<44} {:>10} {:>10}", "light sampling (1 thread)", "ns/vertex", "samples");
    let shapes = [
        ("sphere r=0.5", LightKind::Sphere { radius: 0.5 }),
        ("rect 1x1 (solid angle where large)", LightKind::Rect { width: 1.0, height: 1.0 }),
        ("disk r=0.5", LightKind::Disk { radius: 0.5 }),
        ("cylinder r=0.2 l=2", LightKind::Cylinder { radius: 0.2, length: 2.0 }),
        ("distant 0.53 deg", LightKind::Distant { angle_degrees: 0.53 }),
        ("dome, constant", LightKind::Dome),
    ];
    for (name, kind) in shapes {
        light_row(name, &LightSet::new(vec![light_at(kind, Vec3::ZERO)], 10.0), 1, &points);
    }
    // Many small rect lights on a grid over the box's top, chosen through the light tree.
    for n in [100usize, 10_000] {
        let side = (n as f32).sqrt() as usize;
        let lights = (0..n)
            .map(|i| {
                let at = Vec3::new((i % side) as f32, 0.0, (i / side) as f32) / side as f32 * 9.0 - Vec3::new(4.5, 0.0, 4.5);
                light_at(LightKind::Rect { width: 0.05, height: 0.05 }, at)
            })
            .collect();
        let set = LightSet::new(lights, 10.0);
        for budget in [1, 8] {
            light_row(&format!("{n} rects, tree, split budget {budget}"), &set, budget, &points);
        }
    }
}

fn main() {
    let data = inputs();
    // Build every table before timing, and report what each costs on first use.
    let build = |name: &str, f: &dyn Fn()| {
        let t = Instant::now();
        f();
        println!("table build, first use: {name:<36} {:>8.0} ms", t.elapsed().as_secs_f64() * 1e3);
    };
    build("GGX E(mu, r) 32x32 + E_avg", &|| {
        render_core::bsdf::energy::ggx();
    });
    build("anisotropic GGX E 32x8x8x32 + E_avg", &|| {
        render_core::bsdf::energy::ggx_anisotropic();
    });
    build("glass E(eta, r, mu) 2 x 16x16x32", &|| {
        render_core::bsdf::energy::glass();
    });
    build("dielectric specular E_s 16^3", &|| {
        render_core::bsdf::energy::dielectric_specular();
    });
    build("Disney diffuse energy scales 16x16", &|| {
        render_core::bsdf::disney::diffuse_energy_scales(0.5, 0.0);
    });
    // vertex: eval + pdf + sample at one view, its lookups repeated or prepared once.
    println!(
        "{:<44} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "lobe (1 thread)", "eval+pdf ns", "eval_pdf", "sample ns", "vertex ns", "prepared"
    );
    lobe_row("lambert", &Lobe::Lambert(Lambert { r: Vec3::splat(0.5) }), &data);
    for comp in [false, true] {
        let gold = SpecularFresnel::Gulbrandsen { r: Vec3::new(0.944, 0.776, 0.373), g: Vec3::new(0.998, 0.981, 0.751) };
        lobe_row(
            &format!("metal (Gulbrandsen) r=0.5, compensation {comp}"),
            &Lobe::GgxReflection(GgxReflection::new(0.5, 0.0, gold, comp)),
            &data,
        );
        lobe_row(
            &format!("metal (Gulbrandsen) r=0.5 aniso 0.8, comp. {comp}"),
            &Lobe::GgxReflection(GgxReflection::new(0.5, 0.8, gold, comp)),
            &data,
        );
        lobe_row(
            &format!("glass r=0.5 eta=1.5, compensation {comp}"),
            &Lobe::Dielectric(Dielectric::new(0.5, 0.0, 1.5, Vec3::ONE).compensated(comp)),
            &data,
        );
        let coupling = comp.then_some((1.5, 0.5));
        lobe_row(
            &format!("disney diffuse r=0.5, coupling {comp}"),
            &Lobe::DisneyDiffuse(DisneyDiffuse::new(Vec3::splat(0.5), 0.5, 0.0, coupling, false)),
            &data,
        );
    }
    lobe_row("sheen", &Lobe::Sheen(Sheen { color: Vec3::ONE }), &data);
    lobe_row("clearcoat gloss 0.5", &Lobe::Clearcoat(Clearcoat::new(1.0, 0.5)), &data);
    for comp in [false, true] {
        let plastic = Principled { base_color: Vec3::new(0.8, 0.3, 0.2), roughness: 0.4, ..Default::default() };
        let everything = Principled {
            base_color: Vec3::new(0.8, 0.3, 0.2),
            metallic: 0.3,
            spec_trans: 0.3,
            roughness: 0.4,
            sheen: 0.5,
            clearcoat: 0.5,
            ..Default::default()
        };
        bsdf_row(&format!("principled plastic, compensation {comp}"), &plastic.bsdf(comp), &data);
        bsdf_row(&format!("principled 6 lobes, compensation {comp}"), &everything.bsdf(comp), &data);
    }
    light_table();
}
