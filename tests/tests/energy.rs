//! Energy preservation in whole renders: rough metal and rough glass spheres in a unit white
//! furnace, with and without Kulla-Conty compensation (`--energy-compensation`).

use tessera::remote::RenderOptions;
use tessera_tests::*;

/// Mean red value over the pixels where the camera sees the sphere.
async fn sphere_mean(fixture_name: &str, energy_compensation: bool) -> f64 {
    furnace_sphere_mean(fixture_name, energy_compensation).await
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rough_white_metal_matches_the_background_only_with_compensation() {
    let on = sphere_mean("furnace_rough_metal.usda", true).await;
    let off = sphere_mean("furnace_rough_metal.usda", false).await;
    assert!((on - 1.0).abs() < 0.02, "compensated rough metal: {on}");
    assert!(off < 0.9, "uncompensated rough metal loses energy: {off}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn rough_clear_glass_matches_the_background_only_with_compensation() {
    let on = sphere_mean("furnace_rough_glass.usda", true).await;
    let off = sphere_mean("furnace_rough_glass.usda", false).await;
    assert!((on - 1.0).abs() < 0.02, "compensated rough glass: {on}");
    assert!(off < on - 0.02, "uncompensated rough glass loses energy: {off} vs {on}");
}

/// A film absorbs nothing: smooth glass under one, and a soap bubble's wall (an interface of
/// index 1 under a film, not left out of the scene as bare index-1 glass is), vanish in the
/// furnace in every channel. Within 0.01: the smooth glass fixture's own noise at 64 spp.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn filmed_glass_and_a_soap_bubble_vanish_in_the_furnace() {
    for name in ["furnace_filmed_glass.usda", "furnace_soap_bubble.usda"] {
        let opts = RenderOptions { max_depth: 64, ..small(32, 32, 64) };
        let report = render_fixture(name, &opts).await;
        assert_all_finite(&report.image);
        let (rgb, n) = covered_rgb(&report);
        assert!(n > 100, "{name}: the sphere covers {n} pixels");
        assert!(rgb.iter().all(|c| (c - 1.0).abs() < 0.01), "{name}: {rgb:?}");
    }
}

/// Smooth glass on a coarse mesh (16 x 8 facets) with interpolated normals: it shades with
/// those normals, so its normal AOV turns smoothly from pixel to pixel rather than in
/// facet-sized steps (about 22 degrees), and it still vanishes in the furnace: dropping the
/// directions the facet and the normal disagree on costs little energy.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn coarse_glass_shades_with_smooth_normals_and_keeps_its_energy() {
    let opts = RenderOptions { max_depth: 64, aovs: vec!["normal".into()], ..small(48, 48, 64) };
    let report = render_fixture("furnace_lowpoly_glass.usda", &opts).await;
    assert_all_finite(&report.image);
    let img = &report.image;
    let inside = |x: u32, y: u32| img.pixel("beauty", x, y)[3] == 1.0;
    let (mean, n) = mean_where(img, "beauty", 0, inside);
    assert!(n > 300, "the sphere covers {n} pixels");
    assert!((mean - 1.0).abs() < 0.03, "smooth glass on a coarse mesh in the furnace: {mean}");

    let normal = |x, y| {
        let p = img.pixel("normal", x, y);
        glam::Vec3::new(p[0], p[1], p[2]).normalize()
    };
    let mut worst = 0.0f32;
    for y in 0..img.height {
        for x in 0..img.width - 1 {
            // Whole-pixel neighbours well inside the silhouette.
            let interior = |x: u32, y: u32| {
                x > 0
                    && y > 0
                    && x + 1 < img.width
                    && y + 1 < img.height
                    && inside(x, y)
                    && inside(x - 1, y)
                    && inside(x + 1, y)
                    && inside(x, y - 1)
                    && inside(x, y + 1)
            };
            if interior(x, y) && interior(x + 1, y) {
                worst = worst.max(normal(x, y).angle_between(normal(x + 1, y)).to_degrees());
            }
        }
    }
    assert!(worst < 12.0, "neighbouring normals differ by up to {worst} degrees: facets show");
}
