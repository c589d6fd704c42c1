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
