//! Ray throughput on a 1-million-triangle mesh: BVH build time, closest-hit and occlusion
//! Mrays/s per thread for incoherent rays on 1 and 2 threads, each beside Embree (embreex) on
//! the same data: one thread ray by ray alternating with Embree over three rounds, each round's
//! ratio printed; then 2 threads and batches (several walks in flight per thread,
//! `Blas::intersect_many`) against Embree's best of those rounds on as many threads; then, at
//! the flat BVH's triangle cap, what a commit's rebuild costs and what tracing gains against two
//! levels; then small and medium meshes beside Embree's one thread. Run: `cargo bench -p
//! render-core --bench rays`.

use std::time::Instant;

use glam::{Vec2, Vec3, Vec3A};
use rayon::prelude::*;
use render_core::bvh::{Blas, BuildQuality, FLAT_TRIANGLES, Tlas, TlasInstance};
use render_core::geometry::{Mesh, Ray, Transform};
use render_core::sampling::{Pcg32, uniform_sphere};

/// A bench ray: origin, direction, and the length an occlusion query tests.
struct TestRay {
    o: Vec3,
    d: Vec3,
    tmax: f32,
}

fn write<T: Copy>(path: &std::path::Path, data: &[T]) {
    let bytes = unsafe { std::slice::from_raw_parts(data.as_ptr() as *const u8, std::mem::size_of_val(data)) };
    std::fs::write(path, bytes).expect("write bench data");
}

fn main() {
    let mesh = Mesh::uv_sphere(500, 1000);
    let n_rays = 2_000_000;
    let mut rng = Pcg32::new(42, 7);
    // Incoherent: origins anywhere in a cube around the sphere, directions uniform.
    let rays: Vec<TestRay> = (0..n_rays)
        .map(|_| {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 3.0 - Vec3::splat(1.5);
            let d = uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            TestRay { o, d, tmax: 0.1 + 3.0 * rng.next_f32() }
        })
        .collect();

    let t0 = Instant::now();
    let blas = Blas::build(&mesh, BuildQuality::Medium);
    let build = t0.elapsed().as_secs_f64();

    // This machine's speed drifts by 10-25% over minutes, so the one-thread rows alternate with
    // Embree, on the same mesh and rays, for ROUNDS rounds: each round's ratio is taken against
    // the Embree run just before it, and the spread of those ratios says how far to trust one.
    let dir = write_embree_inputs(&mesh, &rays);
    let lone_pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    let mut rounds = Vec::new();
    let mut embree_runs = Vec::new();
    for _ in 0..ROUNDS {
        let anchor = run_embree(&dir, 2);
        rounds.push((ray_by_ray(&lone_pool, &blas, &rays), anchor.clone()));
        embree_runs.push(anchor);
    }
    let mut results = Vec::new();
    let mut batched = Vec::new();
    for threads in [1, 2] {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        let ((best_c, hits_c), (best_o, hits_o)) = ray_by_ray(&pool, &blas, &rays);
        results.push((threads, n_rays as f64 / best_c / 1e6, n_rays as f64 / best_o / 1e6, hits_c, hits_o));
        batched.push((threads, trace_batched(&pool, &blas, &rays)));
    }
    let embree = embree_runs.into_iter().reduce(best_of_runs).flatten();

    println!("rays: {} triangles, {n_rays} incoherent rays (origins in [-1.5, 1.5]^3, uniform directions)", mesh.indices.len());
    if let Some(kb) = huge_page_kib() {
        // The BVH asks for huge pages (bvh/pages.rs), as Embree does for its own.
        println!(
            "huge pages: {:.1} MB of this process's memory (BVH walked bytes {:.1} MB)",
            kb as f64 / 1024.0,
            blas.walked_bytes() as f64 / 1e6
        );
    }
    print_rounds(&rounds, n_rays);
    let e = |k: &str| embree.as_ref().and_then(|m| m.get(k).copied());
    println!("the rows below against Embree's best of the {ROUNDS} rounds:");
    println!("{:<34} {:>12} {:>14} {:>10}", "measure", "tessera", "embree", "ratio");
    let row = |name: &str, ours: f64, theirs: Option<f64>, higher_is_better: bool| {
        let ratio = theirs.map(|t| if higher_is_better { ours / t } else { t / ours });
        println!(
            "{:<34} {:>12.3} {:>14} {:>10}",
            name,
            ours,
            theirs.map_or("-".into(), |t| format!("{t:.3}")),
            ratio.map_or("-".into(), |r| format!("{r:.2}x"))
        );
    };
    row("BVH build (s)  [ratio: speed]", build, e("build_s"), false);
    // Each row per thread, against Embree on as many threads (two share its scene, as ours
    // share the BVH): two threads contend for the caches and memory, on both sides.
    let embree_on = |threads: usize, k: &str| e(&if threads == 1 { k.to_string() } else { format!("{k}_2t") });
    for &(threads, c, o, hc, ho) in &results {
        let per = threads as f64;
        row(&format!("closest-hit Mrays/s/thread, {threads} thr"), c / per, embree_on(threads, "closest_mrays"), true);
        row(&format!("occlusion Mrays/s/thread, {threads} thr"), o / per, embree_on(threads, "occluded_mrays"), true);
        if let (Some(ec), Some(eo)) = (e("closest_hits"), e("occluded_hits")) {
            println!("  agreement ({threads} thr): closest hits {hc} vs embree {ec}, occluded {ho} vs embree {eo}");
        }
    }
    for (threads, (c, o, hc, ho)) in batched {
        let per = threads as f64;
        row(&format!("batched closest Mrays/s/thr, {threads} thr"), c / per, embree_on(threads, "closest_mrays"), true);
        row(&format!("batched occlusion Mrays/s/thr, {threads} thr"), o / per, embree_on(threads, "occluded_mrays"), true);
        let (hc1, ho1) = (results[0].3, results[0].4);
        println!("  batched hits ({threads} thr): closest {hc} ({}), occluded {ho} ({})", same(hc, hc1), same(ho, ho1));
    }
    flat_at_the_cap(&rays[..n_rays / 4]);
    small_and_medium_meshes();
    terrain();
}

/// Rounds of Embree then ours alternating, one thread each ([`main`]).
const ROUNDS: usize = 3;

/// One round's timings: ours ray by ray ((closest s, hits), (occlusion s, hits)), and the
/// Embree run just before.
type Round = (((f64, usize), (f64, usize)), Option<Numbers>);

/// Each alternating round's rates and ratios, then the range of the ratios.
fn print_rounds(rounds: &[Round], n_rays: usize) {
    let rate = |seconds: f64| n_rays as f64 / seconds / 1e6;
    let mut ratios: [Vec<f64>; 2] = [Vec::new(), Vec::new()];
    for (k, (((c, _), (o, _)), anchor)) in rounds.iter().enumerate() {
        let Some(m) = anchor else { continue };
        let (rc, ro) = (rate(*c) / m["closest_mrays"], rate(*o) / m["occluded_mrays"]);
        println!(
            "round {}: closest {:.3} vs embree {:.3} ({rc:.2}x), occlusion {:.3} vs embree {:.3} ({ro:.2}x) Mrays/s, 1 thread",
            k + 1,
            rate(*c),
            m["closest_mrays"],
            rate(*o),
            m["occluded_mrays"]
        );
        ratios[0].push(rc);
        ratios[1].push(ro);
    }
    let range =
        |r: &[f64]| format!("{:.2}x-{:.2}x", r.iter().copied().fold(f64::INFINITY, f64::min), r.iter().copied().fold(0.0, f64::max));
    if !ratios[0].is_empty() {
        println!("per thread against Embree over the rounds: closest hit {}, occlusion {}", range(&ratios[0]), range(&ratios[1]));
    }
}

/// Closest hits and occlusion ray by ray on `pool`, best of three each.
fn ray_by_ray(pool: &rayon::ThreadPool, blas: &Blas, rays: &[TestRay]) -> ((f64, usize), (f64, usize)) {
    best_of_three(
        pool,
        || {
            rays.par_chunks(4096)
                .map(|c| c.iter().filter(|r| blas.intersect(r.o.into(), r.d.into(), f32::INFINITY, 0.0).is_some()).count())
                .sum()
        },
        || rays.par_chunks(4096).map(|c| c.iter().filter(|r| blas.occluded(r.o.into(), r.d.into(), r.tmax, 0.0)).count()).sum(),
    )
}

/// Meshes of a few dozen to a few hundred triangles, which a BLAS tests whole rather than
/// walks (up to 32 chunks of eight, `bvh::SCAN_MAX_CHUNKS`), and from 320 to 32 768 triangles,
/// walked without asking for nodes ahead (`bvh::NODES_AHEAD_BYTES`): ours on one thread beside
/// Embree's one thread, for rays from inside the mesh's bounds, as a TLAS hands them to an
/// instance.
fn small_and_medium_meshes() {
    println!("\nsmall and medium meshes: 1M rays from origins in [-1.2, 1.2]^3, uniform directions, 1 thread");
    println!("{:<22} {:>16} {:>16} {:>20} {:>14}", "UV sphere", "closest (Mrays/s)", "vs embree", "occlusion (Mrays/s)", "vs embree");
    let mut rng = Pcg32::new(9, 3);
    let rays: Vec<TestRay> = (0..1_000_000)
        .map(|_| {
            let o = Vec3::new(rng.next_f32(), rng.next_f32(), rng.next_f32()) * 2.4 - Vec3::splat(1.2);
            let d = uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
            TestRay { o, d, tmax: 0.1 + 3.0 * rng.next_f32() }
        })
        .collect();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    for (rings, segments) in [
        (2, 3),
        (4, 5),
        (4, 6),
        (4, 8),
        (4, 10),
        (4, 12),
        (4, 14),
        (8, 8),
        (8, 10),
        (8, 12),
        (8, 14),
        (8, 16),
        (10, 16),
        (16, 32),
        (32, 64),
        (64, 256),
    ] {
        let mesh = Mesh::uv_sphere(rings, segments);
        let blas = Blas::build(&mesh, BuildQuality::Medium);
        let ((best_c, hits_c), (best_o, hits_o)) = best_of_three(
            &pool,
            || rays.iter().filter(|r| blas.intersect(r.o.into(), r.d.into(), f32::INFINITY, 0.0).is_some()).count(),
            || rays.iter().filter(|r| blas.occluded(r.o.into(), r.d.into(), r.tmax, 0.0)).count(),
        );
        let (c, o) = (rays.len() as f64 / best_c / 1e6, rays.len() as f64 / best_o / 1e6);
        let embree = run_embree(&write_embree_inputs(&mesh, &rays), 1);
        let e = |k: &str| embree.as_ref().and_then(|m| m.get(k).copied());
        let ratio = |ours: f64, k: &str| e(k).map_or("-".into(), |t| format!("{:.2}x", ours / t));
        let agree = match (e("closest_hits"), e("occluded_hits")) {
            (Some(ec), Some(eo)) if (ec as usize, eo as usize) == (hits_c, hits_o) => "hits agree".to_string(),
            (Some(ec), Some(eo)) => format!("hits {hits_c}/{hits_o} against embree's {ec}/{eo}"),
            _ => String::new(),
        };
        let name = format!("{} triangles", mesh.indices.len());
        println!("{name:<22} {c:>16.2} {:>16} {o:>20.2} {:>14}  {agree}", ratio(c, "closest_mrays"), ratio(o, "occluded_mrays"));
    }
}

/// The `production` bench's terrain (`bench/production_scene.py`: 707 × 707 quads over 40 × 40
/// units, heights within ±1.05) seen from its camera: rays that graze a heightfield, where the
/// sphere's rays start anywhere. Each builder's time and tree, and Embree's one thread, on
/// three sets: camera rays (closest hit), bounce rays leaving the surface the camera rays hit
/// (closest hit) and rays from there towards a dome (occlusion).
fn terrain() {
    let mesh = terrain_mesh();
    let sets = terrain_rays(&mesh, 1_000_000);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap();
    println!("\nterrain: {} triangles, rays of its scene's camera, 1 thread", mesh.indices.len());
    let mut built = Vec::new();
    for (name, quality) in [("binned SAH (the default)", BuildQuality::Medium), ("PLOC (BuildQuality::Fast)", BuildQuality::Fast)] {
        let mut best = f64::INFINITY;
        for _ in 0..3 {
            let t = Instant::now();
            drop(Blas::build(&mesh, quality));
            best = best.min(t.elapsed().as_secs_f64());
        }
        println!("{name:<26} build {best:.3} s (best of 3, all threads)");
        built.push((name, Blas::build(&mesh, quality)));
    }
    println!("{:<8} {:>9} {:>32} {:>32} {:>10}", "rays", "count", built[0].0, built[1].0, "embree");
    for (set, rays) in &sets {
        let occlusion = *set == "shadow";
        let rate = |blas: &Blas| {
            let ((c, _), (o, _)) = best_of_three(
                &pool,
                || rays.iter().filter(|r| blas.intersect(r.o.into(), r.d.into(), f32::INFINITY, 0.0).is_some()).count(),
                || rays.iter().filter(|r| blas.occluded(r.o.into(), r.d.into(), r.tmax, 0.0)).count(),
            );
            rays.len() as f64 / if occlusion { o } else { c } / 1e6
        };
        let ours: Vec<f64> = built.iter().map(|(_, b)| rate(b)).collect();
        let key = if occlusion { "occluded_mrays" } else { "closest_mrays" };
        let embree = run_embree(&write_embree_inputs(&mesh, rays), 1).and_then(|m| m.get(key).copied());
        let cell = |r: f64| embree.map_or(format!("{r:.2} Mrays/s"), |e| format!("{r:.2} Mrays/s ({:.2}x)", r / e));
        let theirs = embree.map_or("-".into(), |e| format!("{e:.2}"));
        println!("{set:<8} {:>9} {:>32} {:>32} {theirs:>10}", rays.len(), cell(ours[0]), cell(ours[1]));
    }
}

/// The terrain of `bench/production_scene.py`: the triangles the USD reader splits its quads
/// into (the same diagonal; winding aside, which no ray query reads).
fn terrain_mesh() -> Mesh {
    const QUADS: u32 = 707;
    const SIZE: f32 = 40.0;
    let height = |x: f32, z: f32| 0.8 * (0.35 * x).sin() * (0.27 * z).cos() + 0.25 * (1.3 * x + 0.7 * z).sin();
    let at = |k: u32| -SIZE / 2.0 + SIZE * k as f32 / QUADS as f32;
    Mesh::grid(QUADS, |i, j| Vec3::new(at(i), height(at(i), at(j)), at(j)))
}

/// `n` camera rays of the scene's camera (at (0, 7, 24), tilted down by atan(6/24), 30 mm lens
/// on a 36 × 20.25 mm film), and from each point they hit a bounce ray (uniform over the
/// hemisphere the camera sees) and a shadow ray towards a dome (uniform over the upper
/// hemisphere, unbounded).
fn terrain_rays(mesh: &Mesh, n: usize) -> [(&'static str, Vec<TestRay>); 3] {
    let blas = Blas::build(mesh, BuildQuality::Medium);
    let mut rng = Pcg32::new(1, 2);
    let eye = Vec3::new(0.0, 7.0, 24.0);
    let tilt = glam::Quat::from_rotation_x(-(6.0f32).atan2(24.0));
    let (mut camera, mut bounce, mut shadow) = (Vec::new(), Vec::new(), Vec::new());
    for _ in 0..n {
        let film = Vec2::new(rng.next_f32() * 2.0 - 1.0, rng.next_f32() * 2.0 - 1.0) * Vec2::new(18.0, 10.125) / 30.0;
        let d = tilt * Vec3::new(film.x, film.y, -1.0).normalize();
        camera.push(TestRay { o: eye, d, tmax: f32::INFINITY });
        let Some((t, tri, _)) = blas.intersect(eye.into(), d.into(), f32::INFINITY, 0.0) else { continue };
        let [a, b, c] = mesh.triangle(tri as usize);
        let facing = (b - a).cross(c - a).normalize();
        let n = if facing.dot(d) > 0.0 { -facing } else { facing };
        let p = eye + d * t + n * 1e-3;
        let w = uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
        bounce.push(TestRay { o: p, d: if w.dot(n) < 0.0 { -w } else { w }, tmax: f32::INFINITY });
        let l = uniform_sphere(Vec2::new(rng.next_f32(), rng.next_f32()));
        shadow.push(TestRay { o: p, d: l.with_y(l.y.abs()), tmax: f32::MAX });
    }
    [("camera", camera), ("bounce", bounce), ("shadow", shadow)]
}

/// The process's anonymous memory in huge pages (Linux), in KiB.
fn huge_page_kib() -> Option<u64> {
    let rollup = std::fs::read_to_string("/proc/self/smaps_rollup").ok()?;
    let line = rollup.lines().find(|l| l.starts_with("AnonHugePages:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// Writes the mesh and rays where `bench/anchors.py rays` reads them; returns the directory.
fn write_embree_inputs(mesh: &Mesh, rays: &[TestRay]) -> std::path::PathBuf {
    let dir = std::env::temp_dir().join("tessera-bench-rays");
    std::fs::create_dir_all(&dir).unwrap();
    write(&dir.join("vertices.bin"), &mesh.positions.iter().flat_map(|p| p.to_array()).collect::<Vec<f32>>());
    write(&dir.join("indices.bin"), &mesh.indices.iter().flatten().copied().collect::<Vec<u32>>());
    write(&dir.join("rays.bin"), &rays.iter().flat_map(|r| [r.o.x, r.o.y, r.o.z, r.d.x, r.d.y, r.d.z, r.tmax]).collect::<Vec<f32>>());
    dir
}

type Numbers = std::collections::HashMap<String, f64>;

/// One run of the Embree anchor (build, then best of three passes of each query on one
/// thread, and on two when `threads` is 2), or None with a message when embreex is missing.
fn run_embree(dir: &std::path::Path, threads: usize) -> Option<Numbers> {
    let script = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../bench/anchors.py");
    match std::process::Command::new("python3").arg(&script).arg("rays").arg(dir).arg(threads.to_string()).output() {
        Ok(out) if out.status.success() => String::from_utf8_lossy(&out.stdout).lines().last().and_then(parse_json_numbers),
        Ok(out) => {
            let why = String::from_utf8_lossy(&out.stderr).lines().last().unwrap_or("").to_string();
            eprintln!("Embree anchor failed (pip install embreex numpy): {why}");
            None
        }
        Err(e) => {
            eprintln!("Embree anchor not run: {e}");
            None
        }
    }
}

/// Embree's best of two runs: the higher rates, the shorter build (hit counts are the same).
fn best_of_runs(a: Option<Numbers>, b: Option<Numbers>) -> Option<Numbers> {
    match (a, b) {
        (Some(mut a), Some(b)) => {
            for (key, value) in b {
                let kept = a.entry(key.clone()).or_insert(value);
                *kept = if key == "build_s" { kept.min(value) } else { kept.max(value) };
            }
            Some(a)
        }
        (a, b) => a.or(b),
    }
}

fn same(a: usize, b: usize) -> &'static str {
    if a == b { "same as ray by ray" } else { "DIFFERENT from ray by ray" }
}

/// The rays in batches of 4096 through `Blas::intersect_many` and `Blas::occluded_many`
/// (several walks in flight per thread): best of three Mrays/s for each, and the hit counts.
fn trace_batched(pool: &rayon::ThreadPool, blas: &Blas, rays: &[TestRay]) -> (f64, f64, usize, usize) {
    let closest: Vec<(Vec3A, Vec3A, f32)> = rays.iter().map(|r| (r.o.into(), r.d.into(), f32::INFINITY)).collect();
    let segments: Vec<(Vec3A, Vec3A, f32)> = rays.iter().map(|r| (r.o.into(), r.d.into(), r.tmax)).collect();
    let count_hits = |c: &[(Vec3A, Vec3A, f32)]| {
        let mut hits = vec![None; c.len()];
        blas.intersect_many(c, 0.0, &mut hits);
        hits.iter().flatten().count()
    };
    let count_blocked = |c: &[(Vec3A, Vec3A, f32)]| {
        let mut blocked = vec![false; c.len()];
        blas.occluded_many(c, 0.0, &mut blocked);
        blocked.iter().filter(|&&b| b).count()
    };
    let ((best_c, hits_c), (best_o, hits_o)) =
        best_of_three(pool, || closest.par_chunks(4096).map(count_hits).sum(), || segments.par_chunks(4096).map(count_blocked).sum());
    let n = rays.len() as f64;
    (n / best_c / 1e6, n / best_o / 1e6, hits_c, hits_o)
}

/// Runs `closest` then `occluded` on `pool`, three rounds: for each, the best time in seconds
/// and the count it returned.
fn best_of_three(
    pool: &rayon::ThreadPool,
    closest: impl Fn() -> usize + Send + Sync,
    occluded: impl Fn() -> usize + Send + Sync,
) -> ((f64, usize), (f64, usize)) {
    let timed = |f: &(dyn Fn() -> usize + Send + Sync)| {
        let t = Instant::now();
        let n = pool.install(f);
        (t.elapsed().as_secs_f64(), n)
    };
    let (mut c, mut o) = ((f64::INFINITY, 0), (f64::INFINITY, 0));
    for _ in 0..3 {
        let tc = timed(&closest);
        c = (c.0.min(tc.0), tc.1);
        let to = timed(&occluded);
        o = (o.0.min(to.0), to.1);
    }
    (c, o)
}

/// The flat BVH at its cap: a scene of [`FLAT_TRIANGLES`] triangles in four instances, built
/// (as every commit rebuilds it) and traced both ways on one thread. The two-level build's
/// time is the TLAS alone: commits reuse BLASes.
fn flat_at_the_cap(rays: &[TestRay]) {
    let rings = (FLAT_TRIANGLES / 4 / 2 / 64) as u32;
    let mesh = Mesh::uv_sphere(rings, 64);
    let blas = vec![std::sync::Arc::new(Blas::build(&mesh, BuildQuality::Medium))];
    let instances: Vec<TlasInstance> = (0..4)
        .map(|i| {
            let xf = glam::Affine3A::from_scale_rotation_translation(
                Vec3::splat(0.5),
                glam::Quat::from_rotation_y(i as f32),
                Vec3::new(if i % 2 == 0 { -0.6 } else { 0.6 }, if i < 2 { -0.6 } else { 0.6 }, 0.0),
            );
            TlasInstance { blas: 0, transform: Transform::new(xf).unwrap(), motion: None }
        })
        .collect();
    let measure = |flat_limit: usize| {
        let (mut build, mut trace) = (f64::INFINITY, f64::INFINITY);
        let mut tlas = None;
        for _ in 0..5 {
            let t = Instant::now();
            tlas = Some(Tlas::build_with_flat_limit(&blas, &instances, flat_limit));
            build = build.min(t.elapsed().as_secs_f64());
        }
        let tlas = tlas.unwrap();
        let mut hits = 0;
        for _ in 0..3 {
            let t = Instant::now();
            hits = rays.iter().filter(|r| tlas.intersect(&blas, &Ray::new(r.o, r.d)).is_some()).count();
            trace = trace.min(t.elapsed().as_secs_f64());
        }
        (build, rays.len() as f64 / trace / 1e6, hits)
    };
    let (flat_build, flat_mrays, flat_hits) = measure(usize::MAX);
    let (two_build, two_mrays, two_hits) = measure(0);
    println!("\nflat BVH at its cap: 4 instances, {} triangles, {} rays, 1 thread", 4 * mesh.indices.len(), rays.len());
    println!("{:<34} {:>12} {:>14} {:>10}", "measure", "flat", "two levels", "ratio");
    println!("{:<34} {:>12.2} {:>14.3} {:>10}", "rebuild per commit (ms)", flat_build * 1e3, two_build * 1e3, "-");
    println!("{:<34} {:>12.3} {:>14.3} {:>9.2}x", "closest-hit Mrays/s", flat_mrays, two_mrays, flat_mrays / two_mrays);
    println!("  agreement: closest hits {flat_hits} flat vs {two_hits} two levels");
}

/// Reads the flat `{"key": number, ...}` object the anchor script prints.
fn parse_json_numbers(line: &str) -> Option<std::collections::HashMap<String, f64>> {
    let body = line.trim().strip_prefix('{')?.strip_suffix('}')?;
    Some(
        body.split(',')
            .filter_map(|kv| {
                let (k, v) = kv.split_once(':')?;
                Some((k.trim().trim_matches('"').to_string(), v.trim().trim_matches('"').parse().ok()?))
            })
            .collect(),
    )
}
