//! Energy preservation in whole renders: rough metal and rough glass spheres in a unit white
//! furnace, with and without Kulla-Conty compensation (`--energy-compensation`).

use tessera::remote::RenderOptions;
use tessera_tests::*;

/// Mean red value over the pixels where the camera sees the sphere.
async fn sphere_mean(fixture_name: &str, energy_compensation: bool) -> f64 {
    let opts = RenderOptions { max_depth: 64, energy_compensation, ..small(32, 32, 64) };
    let report = render_fixture(fixture_name, &opts).await;
    assert_all_finite(&report.image);
    let img = &report.image;
    let (mean, n) = mean_where(img, "beauty", 0, |x, y| img.pixel("beauty", x, y)[3] == 1.0);
    assert!(n > 100, "{fixture_name}: the sphere covers {n} pixels");
    mean
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
