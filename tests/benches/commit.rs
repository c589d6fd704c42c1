//! What an edit costs to commit, by kind, on a production-sized scene: a 1M-triangle mesh,
//! 400 instances of a 5 000-triangle rock, two lights and three materials. Each edit changes
//! one thing in the scene description and commits it with the BLAS cache warm, as a session
//! does after a Sync. Run: `cargo bench -p tessera-tests --bench commit`; results in
//! `docs/service.md`.

use std::sync::Arc;
use std::time::Instant;

use glam::{Affine3A, Vec3};
use render_core::material::ParamValue;
use render_core::scene::{BlasCache, SceneDesc, commit};
use tessera_tests::production_scene;

/// An edit: its name and what it does to the description.
type Edit = (&'static str, fn(&mut SceneDesc));

/// One edit of each kind, applied to the description.
fn edits() -> Vec<Edit> {
    vec![
        ("camera move", |d| d.cameras.get_mut("/Camera").unwrap().transform *= Affine3A::from_translation(Vec3::X * 0.01)),
        ("object transform", |d| d.meshes.get_mut("/World/Hero").unwrap().transform *= Affine3A::from_translation(Vec3::X * 0.01)),
        ("one instance moved", |d| {
            d.instancers.get_mut("/World/Scatter").unwrap().transforms[7] *= Affine3A::from_translation(Vec3::Y * 0.01)
        }),
        ("light intensity", |d| d.lights.get_mut("/Lights/Key").unwrap().intensity *= 1.1),
        ("material roughness", |d| {
            d.materials.get_mut("/M/Hero").unwrap().nodes[0].parameters.insert("roughness".into(), ParamValue::Float(0.5));
        }),
        ("rock points (5k tris)", |d| {
            let rock = d.meshes.get_mut("/World/Rock").unwrap();
            let mut m = (*rock.mesh).clone();
            m.positions.iter_mut().for_each(|p| *p *= 1.01);
            rock.mesh = Arc::new(m);
        }),
    ]
}

fn median_ms(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2] * 1e3
}

fn main() {
    let t = Instant::now();
    render_core::bsdf::energy::warm_up();
    println!(
        "energy tables, all of them: {:.0} ms (once per process, on one thread; a server builds them at start-up)",
        t.elapsed().as_secs_f64() * 1e3
    );
    let mut desc = production_scene();
    let mut cache = BlasCache::default();
    let t = Instant::now();
    commit(&desc, &mut cache).unwrap();
    println!(
        "commit: 1M-triangle mesh + 400 instances of a 5k-triangle rock, 2 lights, 2 materials, {} cores",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    println!("{:<24} {:>10}", "first commit", format!("{:.1} ms", t.elapsed().as_secs_f64() * 1e3));
    let t = Instant::now();
    let unchanged = desc.clone();
    println!("{:<24} {:>10}", "clone of the description", format!("{:.3} ms", t.elapsed().as_secs_f64() * 1e3));
    drop(unchanged);
    for (name, edit) in edits() {
        let times: Vec<f64> = (0..5)
            .map(|_| {
                edit(&mut desc);
                let t = Instant::now();
                let scene = commit(&desc, &mut cache).unwrap();
                let secs = t.elapsed().as_secs_f64();
                drop(scene);
                secs
            })
            .collect();
        println!("{name:<24} {:>10}  (median of 5; BLAS builds in the last: {})", format!("{:.1} ms", median_ms(times)), cache.last_builds);
    }
}
