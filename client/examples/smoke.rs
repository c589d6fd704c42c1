use render_core::{camera::Camera, film::Aov, render::*, scene::*};
fn main() {
    let args: Vec<String> = std::env::args().collect();
    let t = tessera::usd::load(std::path::Path::new(&args[1])).unwrap();
    for w in &t.warnings { println!("warn: {w}"); }
    let desc = t.to_scene_desc();
    let scene = commit(&desc, &mut BlasCache::default()).unwrap();
    print!("{}", scene.plan);
    let settings = RenderSettings { width: 128, height: 128, spp: 64, ..Default::default() };
    let cam = Camera::new(&scene.camera("").unwrap(), settings.width, settings.height);
    let t0 = std::time::Instant::now();
    let (fb, out) = render_to_framebuffer(&scene, &cam, &settings);
    let b = &fb.layers[&Aov::Beauty];
    let mean: f64 = b.chunks(4).map(|p| p[0] as f64).sum::<f64>() / (128.0 * 128.0);
    println!("{:?} mean R {mean} center {:?} rays {} nonfinite {}", t0.elapsed(), &b[(64*128+64)*4..(64*128+64)*4+4], out.stats.rays, out.non_finite);
    let img: Vec<u8> = b.chunks(4).flat_map(|p| [p[0], p[1], p[2]].map(|c| (c.clamp(0.0, 1.0).powf(1.0/2.2) * 255.0) as u8)).collect();
    image::save_buffer(&args[2], &img, 128, 128, image::ExtendedColorType::Rgb8).unwrap();
}
