//! Image-level guarantees: determinism, format independence, the files the CLI writes.

use render_core::integrator::IntegratorSettings;
use tessera::commands::render::{RenderJob, run};
use tessera_tests::*;

fn bits(report: &tessera::remote::RenderReport) -> Vec<u32> {
    report.image.layers.values().flat_map(|(_, d)| d.iter().map(|v| v.to_bits())).collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn renders_are_bit_identical_across_runs_and_thread_counts() {
    let mut opts = small(48, 48, 8);
    opts.aovs = vec!["albedo".into(), "normal".into(), "depth".into()];
    opts.threads = 1;
    let one = render_fixture("cornell_box.usda", &opts).await;
    let again = render_fixture("cornell_box.usda", &opts).await;
    opts.threads = 2;
    let two = render_fixture("cornell_box.usda", &opts).await;
    assert_eq!(bits(&one), bits(&again), "two runs differ");
    assert_eq!(bits(&one), bits(&two), "1 and 2 threads differ");
    // ...and the seed matters.
    opts.seed = 1;
    let reseeded = render_fixture("cornell_box.usda", &opts).await;
    assert_ne!(bits(&one), bits(&reseeded));
}

/// Renders trace camera samples in waves (`trace_wave`: every live path's ray intersected,
/// then every path's step); each sample must come out as it does traced alone (`trace_path`),
/// to the bit, through the specialised loop (Cornell box) and the general one (a volume,
/// subsurface scattering, hair), paths of every length in one wave, waves sharing buffers.
#[test]
fn a_wave_traces_each_path_as_it_is_traced_alone() {
    use render_core::integrator::{IntegratorSettings, PathCounters, WaveBuffers, trace_path, trace_wave};
    use render_core::render::{RenderSettings, camera_path};
    for fixture in ["cornell_box.usda", "usd/volume.usda", "materials/subsurface_lit.usda", "usd/hair.usda"] {
        let scene = render_core::scene::commit(&load(fixture).to_scene_desc(), &mut Default::default()).expect("commits");
        let desc = scene.cameras.values().next().expect("a camera");
        let camera = render_core::camera::Camera::new(desc, 24, 16);
        let settings = RenderSettings { width: 24, height: 16, ..Default::default() };
        let integrator = IntegratorSettings { max_depth: 12, ..Default::default() };
        let samples: Vec<(u32, u32, u32)> = (0..24 * 16 * 3).map(|n| (n % 24, n / 24 % 16, n / 384)).collect();
        // Two waves through the same buffers: nothing of the first may leak into the second.
        let (mut counters, mut buffers, mut waved) = (PathCounters::default(), WaveBuffers::default(), Vec::new());
        for half in samples.chunks(samples.len() / 2) {
            let mut wave: Vec<_> = half.iter().map(|&(x, y, k)| camera_path(&scene, &camera, &settings, x, y, k)).collect();
            let depth_of = |t, cos| camera.depth(t, cos);
            waved.extend_from_slice(trace_wave(
                &scene,
                &mut wave,
                depth_of,
                camera.background_depth(),
                &integrator,
                &mut counters,
                &mut buffers,
            ));
        }
        for (&(x, y, k), in_wave) in samples.iter().zip(&waved) {
            let mut p = camera_path(&scene, &camera, &settings, x, y, k);
            let depth_of = |t| camera.depth(t, p.cos);
            let alone =
                trace_path(&scene, p.ray, depth_of, camera.background_depth(), &mut p.rng, &integrator, &mut PathCounters::default());
            // Debug prints each float's shortest exact form: equal text, equal bits.
            assert_eq!(format!("{in_wave:?}"), format!("{alone:?}"), "{fixture}: sample {k} of pixel ({x}, {y})");
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn usda_usdc_and_usdz_render_identically() {
    let opts = small(32, 32, 4);
    let a = render_fixture("cornell_box.usda", &opts).await;
    let c = render_fixture("cornell_box.usdc", &opts).await;
    let z = render_fixture("cornell_box.usdz", &opts).await;
    assert_eq!(bits(&a), bits(&c), ".usdc differs from .usda");
    assert_eq!(bits(&a), bits(&z), ".usdz differs from .usda");
    // Not trivially equal: the box is lit.
    let (mean, _) = mean_where(&a.image, "beauty", 0, |_, _| true);
    assert!(mean > 0.05, "mean {mean}");
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn cli_render_writes_a_multilayer_exr_and_a_png() {
    let dir = std::env::temp_dir().join(format!("tessera-e2e-{}", std::process::id()));
    let out = dir.join("cornell.exr");
    let mut options = small(40, 30, 4);
    options.aovs = vec!["albedo".into(), "normal".into(), "depth".into()];
    let report = run(&RenderJob::new(fixture("cornell_box.usda"), out.clone(), options)).await.expect("renders");
    let back = tessera::output::read_exr(&out).expect("reads back");
    assert_eq!((back.width, back.height), (40, 30));
    for aov in ["beauty", "albedo", "normal", "depth"] {
        let (c, data) = &back.layers[aov];
        let (c0, original) = &report.image.layers[aov];
        assert_eq!(c, c0, "{aov} channels");
        assert_eq!(data, original, "{aov} pixels survive the EXR round trip");
    }
    // The render reports its own price: one convergence row per pass, spp doubling, noise
    // falling once there are enough samples to estimate it.
    let table = tessera::commands::render::convergence_table(&report.progress);
    assert_eq!(table.lines().count(), 2 + report.progress.len());
    let spp: Vec<u32> = report.progress.iter().map(|p| p.spp).collect();
    assert_eq!(spp, vec![1, 2, 4]);
    assert!(report.progress[2].estimated_noise < report.progress[1].estimated_noise);
    let png = image::open(dir.join("cornell.png")).expect("png preview");
    assert_eq!((png.width(), png.height()), (40, 30));
    std::fs::remove_dir_all(dir).ok();
}

#[test]
fn explain_plan_names_the_effects_and_the_prims_that_call_for_them() {
    let glass = tessera::commands::render::explain_plan(&fixture("furnace_rough_glass.usda"), Default::default()).unwrap();
    assert!(glass.contains("transmission") && glass.contains("/World/Looks/RoughGlass"), "{glass}");
    assert!(!glass.contains("+ metal"), "{glass}");
    let cornell = tessera::commands::render::explain_plan(&fixture("cornell_box.usda"), Default::default()).unwrap();
    assert!(cornell.contains("+ lights") && cornell.contains("/World/Lights/CeilingLight"), "{cornell}");
    assert!(!cornell.contains("+ transmission"), "a scene without glass pays nothing for it: {cornell}");
    assert!(cornell.contains("= path loop          specialised"), "{cornell}");
    // Settings can call for the general loop too, and are named.
    let avoid = IntegratorSettings { caustics: render_core::caustics::CausticMode::Avoid, ..Default::default() };
    let cornell = tessera::commands::render::explain_plan_for(&fixture("cornell_box.usda"), Default::default(), &avoid).unwrap();
    assert!(cornell.contains("= path loop          general, for caustic avoidance"), "{cornell}");
    let volume = tessera::commands::render::explain_plan(&fixture("usd/volume_box.usda"), Default::default()).unwrap();
    assert!(volume.contains("general, for volumes"), "{volume}");
}

/// The render plan changes the price, not the picture: with every effect forced on, each
/// fixture renders the same image within noise (planned and forced, of different seeds,
/// differ no more than two planned renders of different seeds, with 50% slack).
#[test]
fn forcing_every_effect_changes_nothing_but_the_time() {
    let bench = tessera::bench::effects::EffectsBench {
        fixtures: fixture(""),
        names: vec!["cornell_box.usda".into(), "materials/showcase.usda".into(), "furnace_rough_glass.usda".into()],
        size: 48,
        spp: 16,
        out: None,
    };
    let (report, rows) = tessera::bench::effects::effects(&bench).expect("the benchmark runs");
    println!("{report}");
    for r in &rows {
        assert!(
            r.difference < 1.5 * r.noise + 1e-6,
            "{}: planned vs forced {:.3e}, between seeds {:.3e}",
            r.fixture,
            r.difference,
            r.noise
        );
    }
}
