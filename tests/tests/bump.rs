//! `tessera:Bump`: a height read around each shading point tilts the shading normal as the
//! surface it describes would. Fixture: `fixtures/textures/bumped.usda` (`bumped_surfaces()` in
//! make_fixtures.py): a ramp-bumped quad, the plane it describes as geometry, a flat quad and
//! the ramp's bump written in MaterialX (`ND_bump_vector3`), Lambertian (albedo 0.5) under a sun of irradiance π from 30° towards +x, so radiance is
//! 0.5 cos θ with θ between the sun and the shading normal, with no noise: direct light alone
//! from a delta light.

use render_core::camera::Camera;
use render_core::film::Aov;
use render_core::integrator::IntegratorSettings;
use render_core::material::ParamValue;
use render_core::render::{Framebuffer, RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, CommittedScene, commit};
use tessera::usd::Translation;
use tessera_tests::load;

fn render(t: &Translation) -> (Framebuffer, CommittedScene) {
    let scene = commit(&t.to_scene_desc(), &mut BlasCache::default()).expect("commits");
    let camera = Camera::new(&scene.camera("/World/Camera").expect("camera"), 96, 96);
    // Direct light alone: the tilted quad's raised half sees the others' lit tops at grazing
    // angles, light a bump cannot be compared with.
    let integrator = IntegratorSettings { max_depth: 1, ..Default::default() };
    let settings = RenderSettings { width: 96, height: 96, spp: 4, integrator, ..Default::default() };
    let (fb, _) = render_to_framebuffer(&scene, &camera, &settings);
    assert!(fb.layers.values().flatten().all(|v| v.is_finite()), "every AOV finite");
    (fb, scene)
}

/// Red radiance of each pixel at least two pixels inside the prim at `path`: edge pixels mix
/// it with the black background, and the next ones in read the ramp's last texels, where the
/// mip levels a pixel's footprint asks for are clamped (a slope of up to 6% less, measured).
fn inside(fb: &Framebuffer, scene: &CommittedScene, path: &str) -> Vec<f32> {
    let id = scene.prim_paths.iter().position(|p| p == path).expect("prim") as f32 + 1.0;
    let (ids, beauty, w) = (&fb.layers[&Aov::PrimId], &fb.layers[&Aov::Beauty], fb.width as usize);
    let is = |i: usize, dx: isize, dy: isize| {
        let (x, y) = ((i % w) as isize + dx, (i / w) as isize + dy);
        x >= 0 && y >= 0 && (x as usize) < w && ids.get(y as usize * w + x as usize) == Some(&id)
    };
    let around = |i: usize| (-2..=2).all(|d| is(i, d, 0) && is(i, 0, d));
    (0..ids.len()).filter(|&i| around(i)).map(|i| beauty[4 * i]).collect()
}

/// 0.5 cos θ for a shading normal along (−slope, 1, 0), the sun along (sin 30°, cos 30°, 0).
fn lambert(slope: f32) -> f32 {
    let n = glam::Vec3::new(-slope, 1.0, 0.0).normalize();
    0.5 * n.dot(glam::Vec3::new(0.5, 3f32.sqrt() / 2.0, 0.0))
}

#[test]
fn a_bumped_plane_shades_as_the_plane_its_height_describes() {
    let (fb, scene) = render(&load("textures/bumped.usda"));
    // The ramp rises 1/255 a texel: 128/255 a unit of x. 1e-3: the texel's half-float storage.
    let expected = lambert(128.0 / 255.0);
    let quads = [("/World/Ramp", expected), ("/World/Tilted", expected), ("/World/Flat", lambert(0.0)), ("/World/MtlxRamp", expected)];
    assert!(scene.warnings.is_empty(), "{:?}", scene.warnings);
    for (path, want) in quads {
        let px = inside(&fb, &scene, path);
        assert!(px.len() > 100, "{path}: {} pixels", px.len());
        for v in &px {
            assert!((v / want - 1.0).abs() < 1e-3, "{path}: {v}, expected {want}");
        }
    }
    // Leaning the other way (a sign slip) would read lambert(−128/255) = 0.446.
    assert!((expected - 0.2748).abs() < 1e-4, "{expected}");
}

/// Hostile and degenerate bumps: a slope past any float (scale 1e30) and one of zero render
/// finite; a non-finite scale is reported by the node's path and leaves the surface flat.
#[test]
fn extreme_bump_scales_stay_finite_and_a_non_finite_one_is_reported() {
    for (scale, flat) in [(1e30, false), (0.0, true), (f32::NAN, true), (f32::INFINITY, true)] {
        let mut t = load("textures/bumped.usda");
        let (_, network) = t.materials.iter_mut().find(|(p, _)| p == "/World/Looks/Bumped").expect("material");
        let bump = network.nodes.iter_mut().find(|n| n.path.ends_with("/Bump")).expect("bump node");
        bump.parameters.insert("scale".into(), ParamValue::Float(scale));
        let (fb, scene) = render(&t);
        let said = scene.warnings.iter().any(|w| w.contains("/World/Looks/Bumped/Bump") && w.contains("not finite"));
        assert_eq!(said, !scale.is_finite(), "scale {scale}: {:?}", scene.warnings);
        let px = inside(&fb, &scene, "/World/Ramp");
        if flat {
            assert!(px.iter().all(|v| (v / lambert(0.0) - 1.0).abs() < 1e-3), "scale {scale}: {px:?}");
        } else {
            // A vertical cliff's normal lies in the plane, facing −x, away from the sun and the
            // camera; the integrator bends a shading normal that faces away from the viewer
            // back towards it (as it does normal maps', hard.rs). Whatever it shows, it is
            // finite and no brighter than the surface facing the sun (0.5).
            assert!(px.iter().all(|v| (0.0..=0.5).contains(v)), "scale {scale}: {px:?}");
        }
    }
}
