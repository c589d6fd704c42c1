use glam::{Vec2, Vec3};
use render_core::bvh::{Blas, BuildQuality};
use render_core::geometry::Mesh;
use render_core::sampling::{Pcg32, uniform_sphere};

fn main() {
    let args: Vec<usize> = std::env::args().skip(1).map(|a| a.parse().unwrap()).collect();
    let (rings, segs, reps) = (args[0] as u32, args[1] as u32, args[2]);
    let mesh = Mesh::uv_sphere(rings, segs);
    let blas = Blas::build(&mesh, BuildQuality::Medium);
    eprintln!("walked bytes {}", blas.walked_bytes());
    let mut rng = Pcg32::new(9, 3);
    let rays: Vec<(Vec3, Vec3, f32)> = (0..1_000_000)
        .map(|_| {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.4 - Vec3::splat(1.2);
            let d = uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            (o, d, 0.1 + 3.0 * rng.next_f32())
        })
        .collect();
    let mode = std::env::var("MODE").unwrap_or_default();
    let t = std::time::Instant::now();
    let mut hits = 0;
    for _ in 0..reps {
        hits += if mode == "occ" {
            rays.iter().filter(|r| blas.occluded(r.0.into(), r.1.into(), r.2, 0.0)).count()
        } else {
            rays.iter().filter(|r| blas.intersect(r.0.into(), r.1.into(), f32::INFINITY, 0.0).is_some()).count()
        };
    }
    let s = t.elapsed().as_secs_f64();
    println!("{} tris: {:.2} Mrays/s, {} hits", mesh.indices.len(), (reps * rays.len()) as f64 / s / 1e6, hits / reps);
}
