//! What the majorant grid buys: two volumes in the smoke fixture's scene
//! (`fixtures/usd/volume.usda`) rendered in-process on 2 threads with majorant cells of 4³ to
//! 32³ voxels and with one majorant for the whole grid (the anchor: plain delta tracking),
//! alternating, three runs each; prints the median times, the paths per second and the
//! speed-up over the anchor. The volumes: the fixture's smoke ball (dense, smooth: its
//! majorant varies little) and a sparse one, eight small dense puffs in a 128³ grid of empty
//! space, as wisps of smoke are. Every setting renders the same image up to noise (delta
//! tracking is unbiased for any majorant).
//! Run: `cargo bench -p tessera --bench volumes`.

use std::path::Path;
use std::time::Instant;

use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::integrator::IntegratorSettings;
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, CommittedScene, commit};
use render_core::volume::{Volume, VolumeDesc, VoxelGrid};
use std::sync::Arc;

use glam::{Affine3A, IVec3, Quat, UVec3, Vec3};

const WIDTH: u32 = 240;
const HEIGHT: u32 = 160;
const SPP: u32 = 16;
const RUNS: usize = 3;
/// Voxels per majorant cell side; the last covers either volume's whole support (at most 130³
/// voxels: the active ones and the trilinear field's voxel each side) with one cell. A bigger
/// cell would only lengthen the walk outside the grid.
const CELLS: &[i32] = &[4, 8, 16, 32, 130];

/// Eight puffs of radius 6 voxels and density 30 in a 128³ grid spanning the smoke ball's
/// 1.75 units, placed where the smoke was.
fn sparse(smoke: &VolumeDesc) -> VolumeDesc {
    let n = 128i32;
    let mut values = vec![0.0f32; (n * n * n) as usize];
    for k in 0..8 {
        let c = IVec3::new(24 + 80 * (k & 1), 30 + 70 * ((k >> 1) & 1), 20 + 90 * ((k >> 2) & 1));
        for z in -6..=6 {
            for y in -6..=6 {
                for x in -6..=6 {
                    if x * x + y * y + z * z <= 36 {
                        let p = c + IVec3::new(x, y, z);
                        values[(p.x + n * (p.y + n * p.z)) as usize] = 30.0;
                    }
                }
            }
        }
    }
    let index_to_world =
        smoke.index_to_world * Affine3A::from_scale_rotation_translation(Vec3::splat(0.5), Quat::IDENTITY, Vec3::splat(-32.0));
    VolumeDesc {
        density: Arc::new(VoxelGrid { origin: IVec3::ZERO, dims: UVec3::splat(n as u32), values }),
        temperature: None,
        color: None,
        index_to_world,
        shading: smoke.shading,
        motion: Vec::new(),
        link_collections: Vec::new(),
    }
}

fn render(scene: &CommittedScene) -> (f64, f64) {
    let settings = RenderSettings {
        width: WIDTH,
        height: HEIGHT,
        spp: SPP,
        seed: 1,
        tile_size: 16,
        integrator: IntegratorSettings { max_depth: 8, ..Default::default() },
        ..Default::default()
    };
    let camera = Camera::new(&scene.camera("").unwrap(), WIDTH, HEIGHT);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().unwrap();
    let t = Instant::now();
    let (fb, _) = pool.install(|| render_to_framebuffer(scene, &camera, &settings));
    let mean = fb.layers[&Aov::Beauty].chunks(4).map(|p| p[0] as f64).sum::<f64>() / (WIDTH * HEIGHT) as f64;
    (t.elapsed().as_secs_f64(), mean)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures/usd/volume.usda");
    let translation = tessera::usd::load(&path).unwrap();
    println!("volume.usda's scene, {WIDTH}x{HEIGHT}, {SPP} spp, max depth 8, 2 threads, median of {RUNS} alternating runs");
    let (smoke_path, smoke) = translation.volumes[0].clone();
    for (name, volume) in [("smoke ball", smoke.clone()), ("sparse puffs", sparse(&smoke))] {
        println!("{name}:");
        let mut desc = translation.to_scene_desc();
        desc.volumes.insert(smoke_path.clone(), volume);
        compare(&desc);
    }
}

/// Renders `desc` with each majorant cell size and prints the table.
fn compare(desc: &render_core::scene::SceneDesc) {
    let mut scene = commit(desc, &mut BlasCache::default()).unwrap();
    println!("{:>12} {:>8} {:>10} {:>10} {:>12} {:>10}", "cell voxels", "cells", "time s", "Mpaths/s", "mean red", "speed-up");
    render(&scene); // warm caches and tables
    let mut times = vec![Vec::new(); CELLS.len()];
    let mut means = vec![0.0; CELLS.len()];
    let mut cells = vec![0; CELLS.len()];
    for _ in 0..RUNS {
        for (k, &cell) in CELLS.iter().enumerate() {
            scene.volumes = desc.volumes.iter().map(|(p, v)| Volume::with_majorant_cells(p, v, cell)).collect();
            cells[k] = scene.volumes.iter().map(Volume::majorant_cells).sum();
            let (t, mean) = render(&scene);
            times[k].push(t);
            means[k] = mean;
        }
    }
    let anchor = median(times[CELLS.len() - 1].clone());
    let paths = (WIDTH * HEIGHT * SPP) as f64;
    for (k, &cell) in CELLS.iter().enumerate() {
        let t = median(times[k].clone());
        let label = if k == CELLS.len() - 1 { "one cell".to_string() } else { format!("{cell}³") };
        println!("{label:>12} {:>8} {t:>10.3} {:>10.3} {:>12.5} {:>9.2}x", cells[k], paths / t / 1e6, means[k], anchor / t);
    }
}
