//! The price of accuracy with and without denoising: relMSE against an 8192-spp reference
//! and time, raw and denoised (Open Image Denoise), at 4 to 1024 spp on three scenes, and
//! the denoiser's own time per megapixel on 1 and 2 threads. Prints the tables for
//! docs/denoising.md; asserts nothing about time. Needs `pip install pyoidn==2.5.1.0`.
//!
//! `cargo bench -p tessera --bench denoise`

use std::time::Instant;

use tessera::bench::harness::rel_mse;
use tessera::remote::{Connection, RenderOptions};

const SIZE: u32 = 96;
const REFERENCE_SPP: u32 = 8192;
const SPPS: [u32; 5] = [4, 16, 64, 256, 1024];
const SCENES: [&str; 3] = ["cornell_box.usda", "materials/showcase.usda", "caustics/glass_on_floor.usda"];

fn rgb(layer: &(u32, Vec<f32>)) -> Vec<f64> {
    layer.1.chunks(layer.0 as usize).flat_map(|p| p[..3].iter().map(|&x| x as f64)).collect()
}

/// (raw, denoised, render seconds, denoise seconds) of one render.
async fn render(conn: &mut Connection, spp: u32) -> (Vec<f64>, Vec<f64>, f64, f64) {
    let opts = RenderOptions { width: SIZE, height: SIZE, spp, aovs: vec!["albedo".into(), "normal".into()], ..Default::default() };
    let t = Instant::now();
    let mut report = conn.render(&opts, |_| {}).await.expect("renders");
    let render_s = t.elapsed().as_secs_f64();
    let t = Instant::now();
    // A fresh device each time: the time includes loading and creating it, as a CLI run pays.
    let denoiser = tessera::denoise::Denoiser::new(0).expect("OIDN installed (pip install pyoidn==2.5.1.0)");
    tessera::denoise::denoise_image(&mut report.image, &denoiser).unwrap();
    let denoise_s = t.elapsed().as_secs_f64();
    (rgb(&report.image.layers["beauty"]), rgb(&report.image.layers["beauty_denoised"]), render_s, denoise_s)
}

async fn scene_table(name: &str) -> String {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures");
    let translation = tessera::usd::load(&root.join(name)).expect("fixture reads");
    let server = tessera_server::EmbeddedServer::start().await.expect("server");
    let mut conn = Connection::connect(&server.url(), "denoise-bench").await.expect("connects");
    conn.sync_scene(&translation).await.expect("syncs");
    eprintln!("{name}: reference at {REFERENCE_SPP} spp ...");
    let (reference, _, ref_s, _) = render(&mut conn, REFERENCE_SPP).await;
    let mut out = format!(
        "\n### {name} ({SIZE}x{SIZE}; reference {REFERENCE_SPP} spp in {ref_s:.1} s)\n\n| spp | render s | raw relMSE | + denoise s | denoised relMSE |\n| ---: | ---: | ---: | ---: | ---: |\n"
    );
    for spp in SPPS {
        let (raw, denoised, render_s, denoise_s) = render(&mut conn, spp).await;
        out += &format!(
            "| {spp} | {render_s:.3} | {:.5} | {denoise_s:.3} | {:.5} |\n",
            rel_mse(&raw, &reference),
            rel_mse(&denoised, &reference)
        );
    }
    server.stop().await.ok();
    out
}

/// OIDN alone on a 1024x1024 noisy image, per megapixel, after one warm-up run.
fn denoiser_speed(threads: usize) -> f64 {
    let d = tessera::denoise::Denoiser::new(threads).expect("OIDN installed");
    let (w, h) = (1024usize, 1024usize);
    let mut state = 1u32;
    let mut noise = || {
        state = state.wrapping_mul(1664525).wrapping_add(1013904223);
        (state >> 8) as f32 / (1u32 << 24) as f32
    };
    let color: Vec<f32> = (0..w * h * 3).map(|_| noise()).collect();
    let albedo = vec![0.5; w * h * 3];
    let normal: Vec<f32> = (0..w * h).flat_map(|_| [0.0, 0.0, 1.0]).collect();
    d.denoise((w, h), &color, 3, &albedo, &normal).unwrap();
    let t = Instant::now();
    d.denoise((w, h), &color, 3, &albedo, &normal).unwrap();
    t.elapsed().as_secs_f64() / ((w * h) as f64 / 1e6)
}

#[tokio::main]
async fn main() {
    println!("## Denoising: relMSE against the reference and time, raw and denoised");
    for name in SCENES {
        print!("{}", scene_table(name).await);
    }
    println!(
        "\nOIDN alone (RT, hdr, albedo + normal prefiltered), 1024x1024: {:.3} s per megapixel on 1 thread, {:.3} s on 2",
        denoiser_speed(1),
        denoiser_speed(2)
    );
}
