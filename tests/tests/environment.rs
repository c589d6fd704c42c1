//! Textured DomeLights: the latitude-longitude orientation UsdLux specifies, and importance
//! sampling that converges faster than BSDF sampling alone without changing the answer.
//! Fixture: `fixtures/textures/dome.usda` (see `dome()` in make_fixtures.py).

use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::integrator::{IntegratorSettings, LightStrategy};
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, CommittedScene, commit};
use tessera_tests::{load, render_fixture, small};

fn scene() -> CommittedScene {
    commit(&load("textures/dome.usda").to_scene_desc(), &mut BlasCache::default()).expect("commits")
}

/// Beauty RGB of `camera`, `size`², `spp`, with the light strategy given.
fn beauty(scene: &CommittedScene, camera: &str, size: u32, spp: u32, strategy: LightStrategy, seed: u64) -> Vec<f64> {
    let camera = Camera::new(&scene.camera(camera).expect("camera"), size, size);
    let settings = RenderSettings {
        width: size,
        height: size,
        spp,
        seed,
        integrator: IntegratorSettings { strategy, max_depth: 4, ..Default::default() },
        ..Default::default()
    };
    let (fb, _) = render_to_framebuffer(scene, &camera, &settings);
    fb.layers[&Aov::Beauty].chunks(4).flat_map(|p| p[..3].iter().map(|&v| v as f64)).collect()
}

fn rel_mse(img: &[f64], reference: &[f64]) -> f64 {
    img.iter().zip(reference).map(|(a, b)| (a - b).powi(2) / (b * b + 1e-2)).sum::<f64>() / img.len() as f64
}

#[tokio::test(flavor = "multi_thread")]
async fn the_sky_map_faces_the_way_usdlux_says() {
    // make_fixtures.py: +X red, +Z green, -X blue, -Z grey bands in the upper half.
    for (camera, dominant) in
        [("/World/CamPlusX", Some(0)), ("/World/CamPlusZ", Some(1)), ("/World/CamMinusX", Some(2)), ("/World/CamMinusZ", None)]
    {
        let opts = tessera::remote::RenderOptions { camera: camera.into(), ..small(16, 16, 4) };
        let report = render_fixture("textures/dome.usda", &opts).await;
        let (mut sum, n) = ([0.0f64; 3], 256.0);
        for y in 0..16 {
            for x in 0..16 {
                let p = report.image.pixel("beauty", x, y);
                (0..3).for_each(|c| sum[c] += p[c] as f64 / n);
            }
        }
        match dominant {
            Some(c) => assert!((0..3).all(|k| k == c || sum[c] > 4.0 * sum[k]), "{camera}: {sum:?}"),
            None => assert!((sum[0] - 0.4).abs() < 0.02 && (sum[1] - 0.4).abs() < 0.02 && (sum[2] - 0.4).abs() < 0.02, "{camera}: {sum:?}"),
        }
    }
}

#[test]
fn importance_sampling_the_map_beats_bsdf_sampling_and_agrees_with_it() {
    // A white floor under the sky, whose sun (radiance 2000 over four texels) gives most of
    // the light: BSDF sampling finds it rarely, sampling the map finds it nearly always.
    let scene = scene();
    assert!(scene.plan.has(render_core::plan::Feature::EnvironmentMap), "the plan names the map");
    let reference = beauty(&scene, "/World/FloorCam", 16, 1024, LightStrategy::Mis, 1);
    let mis = beauty(&scene, "/World/FloorCam", 16, 16, LightStrategy::Mis, 2);
    let bsdf = beauty(&scene, "/World/FloorCam", 16, 16, LightStrategy::BsdfOnly, 2);
    let (e_mis, e_bsdf) = (rel_mse(&mis, &reference), rel_mse(&bsdf, &reference));
    eprintln!("relMSE at 16 spp: map sampling + MIS {e_mis:.3e}, BSDF sampling alone {e_bsdf:.3e}");
    assert!(e_mis < 0.2 * e_bsdf, "relMSE at 16 spp: map sampling {e_mis:.2e}, BSDF sampling {e_bsdf:.2e}");
    // Unbiased: the mean floor radiance from BSDF sampling alone (many samples) matches.
    let bsdf_many = beauty(&scene, "/World/FloorCam", 16, 1024, LightStrategy::BsdfOnly, 3);
    let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
    let (a, b) = (mean(&reference), mean(&bsdf_many));
    assert!((a - b).abs() < 0.03 * a, "mean radiance: MIS {a:.4}, BSDF only {b:.4}");
}

/// `DomeLight_1` with `poleAxis` "scene": on a Z-up stage the dome's pole follows +Z. The
/// Z-up file is the Y-up one with everything but the dome turned +90° about X, so the two
/// render the same picture (same seed: equal to rounding); a dome that kept its +Y pole would
/// show the camera a different band of sky.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn dome_light_1_poles_follow_the_stage_up_axis() {
    let opts = small(48, 48, 16);
    let y = render_fixture("textures/dome_pole_y.usda", &opts).await.image;
    let z = render_fixture("textures/dome_pole_z.usda", &opts).await.image;
    let (mut diff, mut norm) = (0.0f64, 0.0f64);
    for py in 0..48 {
        for px in 0..48 {
            let (a, b) = (y.pixel("beauty", px, py), z.pixel("beauty", px, py));
            for c in 0..3 {
                diff += ((a[c] - b[c]) as f64).powi(2);
                norm += (a[c] as f64).powi(2);
            }
        }
    }
    let rel = (diff / norm).sqrt();
    println!("Y-up and Z-up DomeLight_1 renders: relative RMS difference {rel:.2e}");
    assert!(rel < 0.02, "the Z-up stage's dome shows another sky: relative RMS {rel}");
    let t = load("textures/dome_pole_z.usda");
    let sky = &t.lights.iter().find(|(p, _)| p == "/World/Sky").expect("the dome").1;
    assert!((sky.transform.transform_vector3(glam::Vec3::Y) - glam::Vec3::Z).length() < 1e-6, "the pole is +Z");
}

/// A textured dome turning 60° over the shutter: each camera sees the mean of the still domes
/// it turns through (eight, at the midpoints of eight equal parts of the turn). About x, the
/// sun it carries climbs and sets over the floor (light sampling's part); about y, the bands
/// of colour pass a camera looking at the horizon (the rays escaping to the sky).
#[test]
fn a_turning_dome_renders_the_mean_of_its_turns() {
    let desc = load("textures/dome.usda").to_scene_desc();
    let with_sky = |transform, motion: Vec<glam::Affine3A>| {
        let mut d = desc.clone();
        let sky = d.lights.get_mut("/World/Sky").unwrap();
        (sky.transform, sky.motion) = (transform, motion);
        commit(&d, &mut BlasCache::default()).expect("commits")
    };
    // Per channel: the bands differ in hue, not in brightness.
    let mean =
        |v: &[f64]| glam::DVec3::from_array(std::array::from_fn(|c| v.iter().skip(c).step_by(3).sum::<f64>() * 3.0 / v.len() as f64));
    for (camera, axis) in [("/World/FloorCam", glam::Vec3::X), ("/World/CamPlusX", glam::Vec3::Y)] {
        let turned = |t: f32| glam::Affine3A::from_axis_angle(axis, t * 60f32.to_radians());
        let turning = with_sky(turned(0.0), (0..17).map(|k| turned(k as f32 / 16.0)).collect());
        assert!(turning.plan.has(render_core::plan::Feature::MotionBlur), "a turning dome blurs");
        let still = |k: usize| mean(&beauty(&with_sky(turned((k as f32 + 0.5) / 8.0), Vec::new()), camera, 16, 256, LightStrategy::Mis, 5));
        let stills: Vec<glam::DVec3> = (0..8).map(still).collect();
        let expected = stills.iter().sum::<glam::DVec3>() / 8.0;
        let seen = mean(&beauty(&turning, camera, 16, 2048, LightStrategy::Mis, 6));
        let spread = stills.iter().fold(0.0f64, |a, s| a.max(((*s - expected) / expected).abs().max_element()));
        eprintln!("{camera}: turning {seen:.4}, mean of stills {expected:.4}, stills within ±{:.0}%", 100.0 * spread);
        // The stills spread wider than the bound, so a dome left at its frame placement fails
        // it; the bound covers the renders' noise and the eight-point mean.
        assert!(spread > 0.2, "{camera}: the turn changes the picture");
        let error = ((seen - expected) / expected).abs().max_element();
        assert!(error < 0.03, "{camera}: turning {seen:.4}, mean of stills {expected:.4}");
    }
}
