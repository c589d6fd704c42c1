//! The white furnace: a white diffuse sphere in a constant dome of radiance 1 reflects
//! exactly 1 everywhere.

use tessera_tests::*;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn white_diffuse_sphere_in_a_unit_dome_is_one_everywhere() {
    let mut opts = small(64, 64, 64);
    opts.aovs = vec!["albedo".into(), "normal".into(), "depth".into()];
    let report = render_fixture("furnace.usda", &opts).await;
    let img = &report.image;
    assert_all_finite(img);
    let alpha = |x, y| img.pixel("beauty", x, y)[3];
    let (sphere, n) = mean_where(img, "beauty", 0, |x, y| alpha(x, y) == 1.0);
    assert!(n > 500, "the sphere covers {n} pixels");
    assert!((sphere - 1.0).abs() < 0.01, "sphere mean {sphere}");
    // Camera rays that miss see the dome itself: exactly 1.
    let (bg, m) = mean_where(img, "beauty", 0, |x, y| alpha(x, y) == 0.0);
    assert!(m > 500 && (bg - 1.0).abs() < 1e-6, "background mean {bg} over {m}");
    // The albedo AOV reports the white material; depth is the camera distance (3 at the front).
    let (albedo, _) = mean_where(img, "albedo", 1, |x, y| alpha(x, y) == 1.0);
    assert!((albedo - 1.0).abs() < 1e-4, "albedo {albedo}");
    let depth = img.pixel("depth", 32, 32)[0];
    assert!((depth - 3.0).abs() < 0.01, "centre depth {depth}");
}
