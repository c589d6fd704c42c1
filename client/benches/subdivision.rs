//! What subdivision costs: a 100k-face Catmull-Clark cage (a cube-sphere, 129 × 129 quads a
//! side, eight extraordinary vertices) refined at levels 1 to 4: time to refine (OpenSubdiv's
//! limit stencils and our tessellation) and to triangulate, and the memory of the triangles
//! the renderer receives. The anchor, in the same run: OpenSubdiv's own uniform refinement to
//! the same level (topology and point positions, `PrimvarRefiner::interpolate`, level by
//! level), which makes the same faces but leaves them on the refined cage rather than on the
//! limit surface, and computes no normals. Refine includes sharing the normals per vertex, as the
//! reader does for a mesh that does not deform. Prints the table for docs/benchmarks.md; asserts
//! nothing.
//!
//! `cargo bench -p tessera --bench subdivision`

use std::time::Instant;

use glam::Vec3;
use tessera::usd::MeshSource;
use tessera::usd::subdivision::{SubdivTags, refine_within, share_normals};

/// A cube-sphere cage of 6·n² quads.
fn cube_sphere(n: usize) -> MeshSource {
    let mut index = std::collections::HashMap::new();
    let (mut points, mut indices) = (Vec::new(), Vec::new());
    for axis in 0..3 {
        for sign in [-1.0f32, 1.0] {
            let mut at = |i: usize, j: usize| {
                let (a, b) = (-1.0 + 2.0 * i as f32 / n as f32, -1.0 + 2.0 * j as f32 / n as f32);
                let mut c = [0.0f32; 3];
                (c[axis], c[(axis + 1) % 3], c[(axis + 2) % 3]) = (sign, a, b);
                let key = c.map(|x| (x * 1e6).round() as i64);
                *index.entry(key).or_insert_with(|| {
                    points.push(Vec3::from(c).normalize());
                    points.len() as i64 - 1
                })
            };
            for j in 0..n {
                for i in 0..n {
                    let quad = [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)];
                    if sign > 0.0 { indices.extend(quad) } else { indices.extend(quad.iter().rev()) }
                }
            }
        }
    }
    let counts = vec![4; indices.len() / 4];
    MeshSource { points, counts, indices, normals: None, uvs: None, primvars: Vec::new(), left_handed: false, smooth: true }
}

/// Seconds for OpenSubdiv's uniform refinement of `cage` to `level`, and the faces it makes.
fn uniform_refinement(cage: &MeshSource, level: usize) -> (f64, usize) {
    use opensubdiv_petite::far::{PrimvarRefiner, TopologyDescriptor, TopologyRefiner, TopologyRefinerOptions, UniformRefinementOptions};
    let t = Instant::now();
    let counts: Vec<u32> = cage.counts.iter().map(|&c| c as u32).collect();
    let indices: Vec<u32> = cage.indices.iter().map(|&i| i as u32).collect();
    let desc = TopologyDescriptor::new(cage.points.len(), &counts, &indices).expect("descriptor");
    let mut refiner = TopologyRefiner::new(desc, TopologyRefinerOptions::default()).expect("refiner");
    refiner.refine_uniform(UniformRefinementOptions { refinement_level: level, ..Default::default() });
    let primvars = PrimvarRefiner::new(&refiner).expect("primvar refiner");
    let mut points: Vec<f32> = cage.points.iter().flat_map(|p| p.to_array()).collect();
    for l in 1..=level {
        points = primvars.interpolate(l, 3, &points).expect("level");
    }
    let faces = refiner.level(level).expect("last level").face_count();
    std::hint::black_box(points);
    (t.elapsed().as_secs_f64(), faces)
}

fn main() {
    let cage = cube_sphere(129);
    let tags = SubdivTags { scheme: "catmullClark".into(), interpolate_boundary: "edgeAndCorner".into(), ..Default::default() };
    println!("cage: {} quads, {} points; machine threads: {}", cage.counts.len(), cage.points.len(), rayon::current_num_threads());
    println!(
        "| level | refined faces | triangles | refine s | OpenSubdiv uniform s (faces) | ratio | triangulate s | mesh MB | bytes/triangle |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for level in 1..=4 {
        let t = Instant::now();
        let mut refined = refine_within(&cage, &tags, level, usize::MAX, |w| eprintln!("{w}")).expect("refines");
        // As the reader does for a mesh that does not deform.
        share_normals(&mut refined.mesh);
        let refine_s = t.elapsed().as_secs_f64();
        let (uniform_s, uniform_faces) = uniform_refinement(&cage, level as usize);
        let t = Instant::now();
        let mesh = tessera::usd::triangulate(&refined.mesh, |w| eprintln!("{w}")).expect("triangulates");
        let triangulate_s = t.elapsed().as_secs_f64();
        let normals = match &mesh.normals {
            render_core::geometry::Attribute::FaceVarying(n) | render_core::geometry::Attribute::Vertex(n) => n.len(),
            render_core::geometry::Attribute::None => 0,
        };
        let bytes = mesh.positions.len() * 12 + mesh.indices.len() * 12 + normals * 12;
        println!(
            "| {level} | {} | {} | {refine_s:.2} | {uniform_s:.2} ({uniform_faces}) | {:.1}x | {triangulate_s:.2} | {:.0} | {:.0} |",
            refined.mesh.counts.len(),
            mesh.indices.len(),
            refine_s / uniform_s,
            bytes as f64 / 1e6,
            bytes as f64 / mesh.indices.len() as f64
        );
    }
}
