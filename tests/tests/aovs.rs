//! AOVs: the light-path components (diffuse, specular, transmission, subsurface, emission) sum to the
//! beauty in every pixel, each holds what its name says, and every AOV is finite.

use tessera::remote::RenderOptions;
use tessera_tests::*;

const COMPONENTS: [&str; 5] = ["diffuse", "specular", "transmission", "subsurface", "emission"];

/// The components that split into direct and indirect parts.
const SPLIT: [&str; 4] = ["diffuse", "specular", "transmission", "subsurface"];

/// Every light-path AOV, direct and indirect parts included.
fn light_path_aovs() -> Vec<String> {
    let parts = SPLIT.iter().flat_map(|c| [format!("{c}_direct"), format!("{c}_indirect")]);
    COMPONENTS.iter().map(|s| s.to_string()).chain(parts).chain(["position".to_string(), "albedo".to_string()]).collect()
}

async fn render_with_components(fixture_name: &str) -> tessera::remote::RenderReport {
    let report = render_fixture(fixture_name, &RenderOptions { aovs: light_path_aovs(), max_depth: 16, ..small(40, 40, 16) }).await;
    assert_all_finite(&report.image);
    report
}

/// Sum of a component's luminance-ish total (all channels) over the image.
fn total(report: &tessera::remote::RenderReport, aov: &str) -> f64 {
    report.image.layers[aov].1.iter().map(|&v| v as f64).sum()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn light_path_components_sum_to_the_beauty() {
    for fixture_name in ["usd/implicit_shapes.usda", "furnace_lowpoly_glass.usda", "cornell_box.usda", "materials/subsurface_lit.usda"] {
        let report = render_with_components(fixture_name).await;
        let img = &report.image;
        for y in 0..img.height {
            for x in 0..img.width {
                let beauty = img.pixel("beauty", x, y);
                for (c, &b) in beauty.iter().take(3).enumerate() {
                    let sum: f64 = COMPONENTS.iter().map(|a| img.pixel(a, x, y)[c] as f64).sum();
                    let b = b as f64;
                    assert!(
                        (sum - b).abs() <= 1e-4 * b.abs().max(1.0),
                        "{fixture_name} ({x}, {y}) channel {c}: components sum to {sum}, beauty {b}"
                    );
                    // Each splits into its direct and indirect parts, neither negative.
                    for name in SPLIT {
                        let total = img.pixel(name, x, y)[c] as f64;
                        let d = img.pixel(&format!("{name}_direct"), x, y)[c] as f64;
                        let i = img.pixel(&format!("{name}_indirect"), x, y)[c] as f64;
                        assert!(
                            (d + i - total).abs() <= 1e-5 * total.max(1.0) && d >= 0.0 && i >= -1e-6 * total.max(1.0),
                            "{fixture_name} ({x}, {y}) {name}: {d} + {i} vs {total}"
                        );
                    }
                }
                // Background pixels are all emission (the dome seen directly).
                if beauty[3] == 0.0 {
                    assert_eq!(img.pixel("emission", x, y)[0], beauty[0], "{fixture_name} ({x}, {y})");
                }
            }
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn each_component_holds_what_its_name_says() {
    // Lambert shapes with a dielectric specular under a dome: diffuse dominates, specular is
    // present, nothing transmits.
    let shapes = render_with_components("usd/implicit_shapes.usda").await;
    assert!(total(&shapes, "diffuse") > 5.0 * total(&shapes, "specular") && total(&shapes, "specular") > 0.0);
    assert_eq!(total(&shapes, "transmission"), 0.0);
    assert_eq!(total(&shapes, "subsurface"), 0.0);
    // Clear glass: no diffuse at all; most light it shows is transmitted.
    let glass = render_with_components("furnace_lowpoly_glass.usda").await;
    assert_eq!(total(&glass, "diffuse"), 0.0);
    assert_eq!(total(&glass, "subsurface"), 0.0);
    assert!(total(&glass, "transmission") > total(&glass, "specular") && total(&glass, "specular") > 0.0);
    // A subsurface sphere on a grey floor: what the sphere transmits enters its medium, so its
    // light is subsurface (far above its reflection), hardly any plain transmission; the
    // floor is diffuse.
    let sss = render_with_components("materials/subsurface_lit.usda").await;
    assert!(total(&sss, "subsurface") > 2.0 * total(&sss, "specular") && total(&sss, "diffuse") > 0.0);
    assert!(total(&sss, "transmission") < 0.01 * total(&sss, "subsurface"));
    // The Cornell box: its light is the only emission the camera sees, so emission is bright
    // where the light is and zero elsewhere.
    let cornell = render_with_components("cornell_box.usda").await;
    assert!(total(&cornell, "emission") > 0.0 && total(&cornell, "specular") == 0.0);
    // Position: the hit point, which lies on the Cornell box's walls (|x| ≤ 1, 0 ≤ y ≤ 2).
    let img = &cornell.image;
    for y in 0..img.height {
        for x in 0..img.width {
            if img.pixel("beauty", x, y)[3] == 1.0 {
                let p = img.pixel("position", x, y);
                assert!(p[0].abs() <= 1.001 && (-0.001..=2.001).contains(&p[1]) && p[2].abs() <= 1.001, "({x}, {y}): {p:?}");
            }
        }
    }
}

/// Direct light is what one bounce finds: the Cornell box's diffuse_direct at depth 16 is, pixel
/// for pixel, its diffuse at depth 1 (the same samples reach the first surface either way),
/// and the indirect part is what the deeper paths add. Behind a subsurface boundary, direct
/// light is what reaches the medium from the light before the path meets another surface.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn direct_parts_are_what_one_bounce_finds() {
    let (server, mut conn) = session_with(&load("cornell_box.usda")).await;
    let opts = |max_depth| RenderOptions { aovs: light_path_aovs(), max_depth, ..small(24, 24, 16) };
    let deep = conn.render(&opts(16), |_| {}).await.unwrap();
    let one = conn.render(&opts(1), |_| {}).await.unwrap();
    let (direct, single) = (&deep.image.layers["diffuse_direct"].1, &one.image.layers["diffuse"].1);
    for (k, (d, s)) in direct.iter().zip(single).enumerate() {
        assert!((d - s).abs() <= 1e-5 * s.max(1.0), "value {k}: direct {d} at depth 16, diffuse {s} at depth 1");
    }
    assert_eq!(total(&one, "diffuse_indirect"), 0.0);
    let (d, i) = (total(&deep, "diffuse_direct"), total(&deep, "diffuse_indirect"));
    println!("cornell box: diffuse direct {d:.1}, indirect {i:.1}");
    assert!(i > 0.2 * d && i < d, "diffuse direct {d}, indirect {i}");
    conn.close().await.ok();
    server.stop().await.unwrap();
    let sss = render_fixture(
        "materials/subsurface_lit.usda",
        &RenderOptions { aovs: light_path_aovs(), avoid_caustics: true, max_depth: 16, ..small(40, 30, 16) },
    )
    .await;
    let (d, i) = (total(&sss, "subsurface_direct"), total(&sss, "subsurface_indirect"));
    println!("subsurface sphere: direct {d:.2}, indirect {i:.2}");
    assert!(d > i && i > 0.0, "subsurface direct {d}, indirect {i}");
}

/// Every AOV is finite everywhere on every fixture (a NaN anywhere would poison a compositor).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn every_aov_is_finite_on_every_fixture() {
    let aovs: Vec<String> = render_core::film::Aov::ALL.iter().skip(1).map(|a| a.name().to_string()).collect();
    for path in all_fixtures() {
        let translation = tessera::usd::load(&path).unwrap_or_else(|e| panic!("{}: {e:#}", path.display()));
        let (server, mut conn) = session_with(&translation).await;
        let report = conn.render(&RenderOptions { aovs: aovs.clone(), ..small(12, 12, 2) }, |_| {}).await.expect("renders");
        server.stop().await.expect("server stops");
        assert_eq!(report.image.layers.len(), aovs.len() + 1, "{}", path.display());
        assert_all_finite(&report.image);
    }
}

/// The primId AOV labels each pixel with the prim its first camera sample hit, through the
/// table `Started` sends (and the EXR header keeps): the furnace sphere in the middle, nothing
/// (0) in the corners; ids are whole numbers, never averaged.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn prim_ids_name_the_prim_each_pixel_sees() {
    let opts = tessera::remote::RenderOptions { aovs: vec!["primId".into()], ..small(24, 24, 4) };
    let report = render_fixture("furnace.usda", &opts).await;
    let ids = &report.image.layers["primId"].1;
    let table = &report.started.prim_paths;
    assert!(ids.iter().all(|&id| id.fract() == 0.0 && id >= 0.0 && (id as usize) <= table.len()), "ids {ids:?}");
    let at = |x: usize, y: usize| ids[y * 24 + x] as usize;
    assert_eq!(table[at(12, 12) - 1], "/World/Sphere");
    assert_eq!(at(0, 0), 0);
}
