//! The sampler: Owen-scrambled Sobol beats independent random numbers at equal spp, and the
//! error of both falls with spp as Monte Carlo says it should.

use tessera::remote::RenderOptions;
use tessera_tests::*;

fn beauty_rgb(report: &tessera::remote::RenderReport) -> Vec<f64> {
    report.image.layers["beauty"].1.chunks(4).flat_map(|p| [p[0] as f64, p[1] as f64, p[2] as f64]).collect()
}

/// Relative MSE with Rousselle's ε = 0.01.
fn rel_mse(img: &[f64], reference: &[f64]) -> f64 {
    img.iter().zip(reference).map(|(a, r)| (a - r).powi(2) / (r * r + 0.01)).sum::<f64>() / img.len() as f64
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn sobol_beats_independent_numbers_and_error_falls_with_spp_on_the_cornell_box() {
    let (w, h) = (48, 48);
    let opts = |spp, seed, sobol| RenderOptions { seed, sobol, max_depth: 7, ..small(w, h, spp) };
    let (server, mut conn) = session_with(&load("cornell_box.usda")).await;
    let reference = beauty_rgb(&conn.render(&opts(2048, 1000, true), |_| {}).await.unwrap());
    let mut rows = Vec::new();
    for spp in [4u32, 16, 64] {
        // Averaged over seeds, so the comparison is about the sampler, not one draw.
        let (mut sobol, mut indep) = (0.0, 0.0);
        for seed in 0..3 {
            sobol += rel_mse(&beauty_rgb(&conn.render(&opts(spp, seed, true), |_| {}).await.unwrap()), &reference) / 3.0;
            indep += rel_mse(&beauty_rgb(&conn.render(&opts(spp, seed, false), |_| {}).await.unwrap()), &reference) / 3.0;
        }
        println!("cornell {w}x{h}, {spp} spp: relMSE sobol {sobol:.5}, independent {indep:.5} ({:.2}x)", indep / sobol);
        rows.push((spp, sobol, indep));
    }
    server.stop().await.unwrap();
    for &(spp, sobol, indep) in &rows {
        assert!(sobol < 0.9 * indep, "{spp} spp: Sobol {sobol} is not clearly below independent {indep}");
    }
    // MSE falls at least as 1/spp (16x the samples, under a third of the error as slack
    // for the reference's own noise), for both samplers.
    let (first, last) = (rows[0], rows[2]);
    assert!(last.1 < first.1 / 5.0 && last.2 < first.2 / 5.0, "error does not fall with spp: {rows:?}");
}

/// The firefly clamp is off by default; on, it is reported, lowers the variance between
/// seeds and darkens the image (its bias), on the Cornell box's indirect light (measured on
/// the ceiling's corners at 8 spp: clamp 0.2 cut the variance 2.7x and the mean by 12%).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_firefly_clamp_trades_variance_for_a_reported_bias() {
    let (server, mut conn) = session_with(&load("cornell_box.usda")).await;
    let opts = |seed, clamp| RenderOptions { seed, clamp_indirect: clamp, max_depth: 7, ..small(32, 32, 8) };
    let mut stats = Vec::new();
    for clamp in [None, Some(0.2)] {
        let a = conn.render(&opts(1, clamp), |_| {}).await.unwrap();
        let b = conn.render(&opts(2, clamp), |_| {}).await.unwrap();
        let said = a.started.warnings.iter().any(|w| w.contains("firefly clamp"));
        assert_eq!(said, clamp.is_some(), "the clamp is reported exactly when it is on: {:?}", a.started.warnings);
        // The ceiling's corners (top rows, away from the light in the middle) see no direct
        // light: everything there is indirect, which is what the clamp acts on.
        let ceiling: Vec<usize> =
            (0..3u32).flat_map(|y| (0..32u32).filter(|x| !(10..22).contains(x)).map(move |x| (y * 32 + x) as usize)).collect();
        let (pa, pb) = (beauty_rgb(&a), beauty_rgb(&b));
        let values = |p: &[f64]| ceiling.iter().flat_map(|&i| p[3 * i..3 * i + 3].to_vec()).collect::<Vec<f64>>();
        let (pa, pb) = (values(&pa), values(&pb));
        let mean = (pa.iter().sum::<f64>() + pb.iter().sum::<f64>()) / (2 * pa.len()) as f64;
        let spread = pa.iter().zip(&pb).map(|(x, y)| (x - y).powi(2)).sum::<f64>() / pa.len() as f64;
        println!("clamp {clamp:?}: mean {mean}, spread {spread}");
        stats.push((mean, spread));
    }
    server.stop().await.unwrap();
    let ((mean_off, var_off), (mean_on, var_on)) = (stats[0], stats[1]);
    assert!(var_on < 0.7 * var_off, "clamping does not reduce variance: {var_on} vs {var_off}");
    assert!(mean_on < 0.98 * mean_off, "clamping must lose energy (its bias): {mean_on} vs {mean_off}");
}

/// `tessera bench accuracy` at a small size: the report and its plot are written, and the
/// numbers behind them say what they should (error falls with spp and with depth; Sobol
/// below independent; compensation brings the furnace to 1).
#[test]
fn the_accuracy_report_measures_what_the_knobs_do() {
    let dir = std::env::temp_dir().join(format!("tessera-accuracy-{}", std::process::id()));
    let out = dir.join("accuracy.md");
    let bench = tessera::bench::accuracy::AccuracyBench { fixtures: fixture(""), out: out.clone(), size: 24, reference_spp: 1024 };
    let (md, s) = tessera::bench::accuracy::accuracy(&bench).expect("the benchmark runs");
    assert!(md.contains("Max depth") && std::fs::metadata(out.with_extension("svg")).is_ok_and(|m| m.len() > 1000));
    for (name, curve) in &s.spp_curves {
        let (first, last) = (curve.first().unwrap().2, curve.last().unwrap().2);
        assert!(last < first / 30.0, "{name}: relMSE {first} at 1 spp, {last} at 256");
        assert!(last > 3.0 * s.reference_noise, "{name}: the reference is too noisy to measure {last}");
    }
    let at = |name: &str, i: usize| s.spp_curves.iter().find(|(n, _)| n == name).unwrap().1[i].2;
    assert!(at("Sobol", 4) < at("independent", 4), "Sobol at 256 spp");
    assert!(s.depth[0].1 > 5.0 * s.depth[4].1, "one bounce misses most indirect light: {:?}", s.depth);
    for (scene, on, mean) in &s.furnace {
        if *on {
            assert!((mean - 1.0).abs() < 0.02, "{scene} with compensation: {mean}");
        } else {
            assert!(*mean < 0.9, "{scene} without compensation: {mean}");
        }
    }
    // Texture filtering buys less error at few samples; the subsurface and many-light rows
    // are measured (their values are in docs/accuracy-vs-time.md).
    let tf = |label: &str| s.texture_filtering.iter().find(|(l, ..)| l == label).unwrap_or_else(|| panic!("no row {label}")).2;
    assert!(tf("4 spp, filtering on") < tf("4 spp, filtering off"), "{:?}", s.texture_filtering);
    assert_eq!(s.subsurface.len(), 6);
    // Behind a smooth boundary, avoidance's transparent shadows cut the noise by far more than
    // their bias (within 10% where full path tracing converges).
    let smooth = |label: &str| s.subsurface_smooth.iter().find(|(l, ..)| l == label).unwrap_or_else(|| panic!("no row {label}")).2;
    assert!(smooth("64 spp, caustics avoid") < smooth("64 spp, caustics full") / 10.0, "{:?}", s.subsurface_smooth);
    assert!(s.subsurface_smooth_bias.iter().all(|r| (0.95..1.10).contains(r)), "{:?}", s.subsurface_smooth_bias);
    assert!(s.many_lights.len() == 16 && s.many_lights.iter().all(|r| r.many_spp >= 1 && r.ratio.is_finite()), "{:?}", s.many_lights);
    std::fs::remove_dir_all(&dir).ok();
}

/// Adaptive sampling on a nearly noiseless image: a white diffuse sphere in the white furnace
/// is 1 within about 1% on every path (the tessellation's shading normals), far below a 5%
/// target, so every pixel retires after the minimum 16 samples and the render ends early.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn adaptive_sampling_stops_a_noiseless_image_at_the_minimum() {
    let opts = RenderOptions { noise_threshold: Some(0.05), aovs: vec!["sampleCount".into()], ..small(24, 24, 256) };
    let report = render_fixture("furnace.usda", &opts).await;
    let counts = &report.image.layers["sampleCount"].1;
    let odd: Vec<(usize, f32)> = counts.iter().copied().enumerate().filter(|(_, c)| *c != 16.0).collect();
    assert!(
        odd.is_empty(),
        "sample counts other than 16: {odd:?}; beauty there {:?}",
        odd.iter().map(|(i, _)| &report.image.layers["beauty"].1[4 * i..4 * i + 4]).collect::<Vec<_>>()
    );
    assert_eq!(report.finished.mean_spp, 16.0);
    // The counters see exactly the samples taken, each at least one ray.
    assert_eq!(report.finished.paths, 16 * 24 * 24);
    assert!(report.finished.rays >= report.finished.paths, "rays {} for {} paths", report.finished.rays, report.finished.paths);
    assert_eq!(report.progress.last().unwrap().active_pixels, 0);
}

/// On the Cornell box, adaptive sampling spends fewer samples where the image is easy, the
/// pixels it retired are below the target by their own variance, and the image stays
/// unbiased: its mean matches a uniform render of the full budget within their noise.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn adaptive_sampling_retires_converged_pixels_without_bias() {
    let threshold = 0.1f32;
    let (w, h) = (32, 32);
    let aovs = vec!["sampleCount".to_string(), "variance".to_string()];
    // 8-px tiles: the final stats count samples per tile, 16 regions here.
    let base = RenderOptions { max_depth: 7, aovs, tile_size: 8, ..small(w, h, 256) };
    let (server, mut conn) = session_with(&load("cornell_box.usda")).await;
    let uniform = conn.render(&base, |_| {}).await.unwrap();
    let adaptive = conn.render(&RenderOptions { noise_threshold: Some(threshold), ..base.clone() }, |_| {}).await.unwrap();
    let img = &adaptive.image;
    let counts = &img.layers["sampleCount"].1;
    let (lo, hi) = counts.iter().fold((f32::MAX, 0.0f32), |(lo, hi), &c| (lo.min(c), hi.max(c)));
    println!(
        "cornell {w}x{h}, target {threshold}: mean {:.1} spp of 256, per pixel {lo}..{hi}; {}",
        adaptive.finished.mean_spp,
        tessera::commands::render::adaptive_summary(&adaptive, threshold)
    );
    assert!(lo >= 16.0 && hi <= 256.0 && lo < hi, "sample counts {lo}..{hi}");
    assert!(adaptive.finished.mean_spp < 0.9 * 256.0, "adaptive sampling saved nothing: {}", adaptive.finished.mean_spp);
    // The final stats say where the samples went: the regions tile the image, each one's count
    // is its pixels' sampleCount, and the easy regions took fewer than the hard ones.
    let regions = &adaptive.finished.regions;
    assert_eq!(regions.iter().map(|r| r.width * r.height).sum::<u32>(), w * h);
    for r in regions {
        let counted: f64 = (r.y..r.y + r.height)
            .flat_map(|y| (r.x..r.x + r.width).map(move |x| (x, y)))
            .map(|(x, y)| counts[(y * w + x) as usize] as f64)
            .sum();
        assert_eq!(r.mean_spp * (r.width * r.height) as f64, counted, "region {r:?}");
    }
    let (least, most) = regions.iter().fold((f64::MAX, 0.0f64), |(lo, hi), r| (lo.min(r.mean_spp), hi.max(r.mean_spp)));
    assert!(least < 0.75 * most, "regions took {least}..{most} spp");
    // Neighbourhoods cross tile edges, so the tile size changes nothing: one 32-px tile gives
    // the same pixels, sample for sample.
    let one_tile = conn.render(&RenderOptions { noise_threshold: Some(threshold), tile_size: 32, ..base.clone() }, |_| {}).await.unwrap();
    assert_eq!(one_tile.image.layers["beauty"].1, img.layers["beauty"].1);
    assert_eq!(&one_tile.image.layers["sampleCount"].1, counts);
    // Every retired pixel's own relative standard error is below the target.
    let beauty = &img.layers["beauty"].1;
    let variance = &img.layers["variance"].1;
    for i in 0..(w * h) as usize {
        if counts[i] < hi {
            let lum = 0.2126 * beauty[4 * i] + 0.7152 * beauty[4 * i + 1] + 0.0722 * beauty[4 * i + 2];
            assert!(variance[i].sqrt() / (lum + 1e-3) < threshold, "pixel {i}: retired with error {}", variance[i].sqrt() / (lum + 1e-3));
        }
    }
    // Unbiased: the image means agree within a few standard errors of their difference.
    let mean = |r: &tessera::remote::RenderReport| beauty_rgb(r).iter().sum::<f64>() / (3 * w * h) as f64;
    let (mu, ma) = (mean(&uniform), mean(&adaptive));
    let se =
        |r: &tessera::remote::RenderReport| r.image.layers["variance"].1.iter().map(|&v| v as f64).sum::<f64>().sqrt() / (w * h) as f64;
    let tolerance = 4.0 * (se(&uniform).powi(2) + se(&adaptive).powi(2)).sqrt() + 1e-4;
    assert!((mu - ma).abs() < tolerance, "uniform mean {mu}, adaptive {ma}, tolerance {tolerance}");
    conn.close().await.ok();
    server.stop().await.unwrap();
}

/// MIS combinations are unbiased: BSDF sampling alone, next-event estimation alone and their
/// MIS combination render the same image mean within noise (the Cornell box's area light and
/// the showcase's glossy and rough lobes), and MIS has the lowest variance of the three on the
/// glossy scene.
#[test]
fn bsdf_only_light_only_and_mis_agree_within_noise() {
    use render_core::integrator::{IntegratorSettings, LightStrategy};
    use render_core::render::{RenderSettings, render_to_framebuffer};
    for (name, spp) in [("cornell_box.usda", 256u32), ("materials/showcase.usda", 128)] {
        let t = load(name);
        let scene = render_core::scene::commit(&t.to_scene_desc(), &mut render_core::scene::BlasCache::default()).unwrap();
        let (w, h) = (32u32, 24u32);
        let camera = render_core::camera::Camera::new(&scene.camera("").unwrap(), w, h);
        let mut rows = Vec::new();
        for strategy in [LightStrategy::Mis, LightStrategy::BsdfOnly, LightStrategy::LightOnly] {
            let settings = RenderSettings {
                width: w,
                height: h,
                spp,
                integrator: IntegratorSettings { max_depth: 6, strategy, ..Default::default() },
                ..Default::default()
            };
            let (fb, _) = render_to_framebuffer(&scene, &camera, &settings);
            let lum: Vec<f64> = fb.layers[&render_core::film::Aov::Beauty]
                .chunks(4)
                .map(|p| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64)
                .collect();
            let var: f64 = fb.layers[&render_core::film::Aov::Variance].iter().map(|&v| v as f64).sum();
            let n = lum.len() as f64;
            rows.push((strategy, lum.iter().sum::<f64>() / n, var.sqrt() / n, var / n));
        }
        println!("{name}: {rows:?}");
        let (mis_mean, mis_se, mis_var) = (rows[0].1, rows[0].2, rows[0].3);
        for &(strategy, mean, se, _) in &rows[1..] {
            let tolerance = 4.0 * (se * se + mis_se * mis_se).sqrt();
            assert!((mean - mis_mean).abs() < tolerance, "{name}: {strategy:?} mean {mean} vs MIS {mis_mean} (tolerance {tolerance})");
        }
        if name.contains("showcase") {
            assert!(mis_var < rows[1].3 && mis_var < rows[2].3, "{name}: MIS variance {mis_var} vs {:?}", rows);
        }
    }
}
