//! AOVs: the light-path components (diffuse, specular, transmission, subsurface, emission) sum to the
//! beauty in every pixel, each holds what its name says, and every AOV is finite.

use tessera::remote::RenderOptions;
use tessera_tests::*;

const COMPONENTS: [&str; 5] = ["diffuse", "specular", "transmission", "subsurface", "emission"];

async fn render_with_components(fixture_name: &str) -> tessera::remote::RenderReport {
    let aovs = COMPONENTS.iter().map(|s| s.to_string()).chain(["position".to_string(), "albedo".to_string()]).collect();
    let report = render_fixture(fixture_name, &RenderOptions { aovs, max_depth: 16, ..small(40, 40, 16) }).await;
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
                for c in 0..3 {
                    let sum: f64 = COMPONENTS.iter().map(|a| img.pixel(a, x, y)[c] as f64).sum();
                    let b = beauty[c] as f64;
                    assert!(
                        (sum - b).abs() <= 1e-4 * b.abs().max(1.0),
                        "{fixture_name} ({x}, {y}) channel {c}: components sum to {sum}, beauty {b}"
                    );
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
