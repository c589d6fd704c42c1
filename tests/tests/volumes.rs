//! UsdVol volumes rendered: Beer-Lambert transmittance through an absorbing box, the white
//! furnace of a scattering-only volume, an emitting slab against its closed form, and a
//! scene without volumes left as it was.

use std::sync::Arc;

use glam::{Affine3A, IVec3, Quat, UVec3, Vec3};
use render_core::camera::{Camera, CameraDesc};
use render_core::film::Aov;
use render_core::integrator::IntegratorSettings;
use render_core::light::{LightDesc, LightKind};
use render_core::plan::Feature;
use render_core::render::{RenderSettings, render_to_framebuffer};
use render_core::scene::{BlasCache, SceneDesc, commit};
use render_core::volume::{VolumeDesc, VolumeShading, VoxelGrid};

/// `n`³ voxels of 1 over the unit cube: voxel i covers [i/n, (i + 1)/n], its value at the
/// centre, so the trilinear field integrates to exactly 1 along any axis-parallel line
/// through the interior (half-voxel ramps at each end).
fn unit_box(n: u32, shading: VolumeShading) -> VolumeDesc {
    VolumeDesc {
        density: Arc::new(VoxelGrid { origin: IVec3::ZERO, dims: UVec3::splat(n), values: vec![1.0; (n * n * n) as usize] }),
        temperature: None,
        color: None,
        index_to_world: Affine3A::from_scale_rotation_translation(Vec3::splat(1.0 / n as f32), Quat::IDENTITY, Vec3::splat(0.5 / n as f32)),
        shading,
        motion: Vec::new(),
        link_collections: Vec::new(),
    }
}

/// A dome of radiance 1 and an orthographic camera 0.6 units wide looking down −Z at the box.
fn scene_with(volume: VolumeDesc) -> SceneDesc {
    let mut desc = SceneDesc::default();
    desc.lights.insert("/Dome".into(), LightDesc::new(LightKind::Dome, Affine3A::IDENTITY, 1.0));
    let camera = CameraDesc {
        transform: Affine3A::from_translation(Vec3::new(0.5, 0.5, 3.0)),
        orthographic: true,
        horizontal_aperture: 6.0,
        vertical_aperture: 6.0,
        near: 0.01,
        ..Default::default()
    };
    desc.cameras.insert("/Cam".into(), camera);
    desc.volumes.insert("/Vol".into(), volume);
    desc
}

/// Mean beauty (RGB) over the image.
fn mean_beauty(desc: &SceneDesc, size: u32, spp: u32, max_depth: u32) -> (Vec3, f32) {
    let scene = commit(desc, &mut BlasCache::default()).expect("commits");
    assert!(scene.plan.has(Feature::Volumes), "the plan lists the volume");
    let camera = Camera::new(&scene.camera("/Cam").expect("camera"), size, size);
    let integrator = IntegratorSettings { max_depth, ..Default::default() };
    let settings = RenderSettings { width: size, height: size, spp, integrator, ..Default::default() };
    let (fb, _) = render_to_framebuffer(&scene, &camera, &settings);
    let px = &fb.layers[&Aov::Beauty];
    let n = (size * size) as f32;
    let sum = px.chunks(4).fold(Vec3::ZERO, |s, p| s + Vec3::new(p[0], p[1], p[2]));
    let alpha = px.chunks(4).map(|p| p[3]).sum::<f32>() / n;
    assert!(px.iter().all(|v| v.is_finite()));
    (sum / n, alpha)
}

#[test]
fn an_absorbing_box_transmits_as_beer_lambert_says() {
    for sigma in [0.5f32, 2.0, 6.0] {
        let shading = VolumeShading { density: sigma, color: Vec3::ZERO, ..Default::default() };
        let (mean, alpha) = mean_beauty(&scene_with(unit_box(16, shading)), 16, 256, 8);
        // Every camera ray crosses one unit of the box: e^(−σ). 65 536 Bernoulli escapes:
        // σ ≤ 0.002; 5σ bounds.
        let expected = (-sigma).exp();
        let bound = 5.0 * (expected * (1.0 - expected) / 65_536.0).sqrt();
        assert!((mean - Vec3::splat(expected)).abs().max_element() < bound, "σ = {sigma}: {mean} vs {expected}");
        // Coverage is the share of camera rays the volume stopped.
        assert!((alpha - (1.0 - expected)).abs() < bound, "σ = {sigma}: alpha {alpha}");
    }
}

#[test]
fn a_white_scattering_volume_in_a_white_furnace_vanishes() {
    for (sigma, g) in [(1.0f32, 0.0f32), (8.0, 0.7), (8.0, -0.5)] {
        let shading = VolumeShading { density: sigma, color: Vec3::ONE, anisotropy: g, ..Default::default() };
        let (mean, _) = mean_beauty(&scene_with(unit_box(8, shading)), 16, 256, 1000);
        // Radiance 1 everywhere; losses only by depth 1000 (none) and roulette is unbiased.
        // Noise comes from roulette and the bounce count: 65 536 paths measured within 0.004
        // of 1 (2026-12-03); 0.01 bounds.
        assert!((mean - Vec3::ONE).abs().max_element() < 0.01, "σ = {sigma}, g = {g}: {mean}");
    }
}

/// A colour field tints the albedo per channel: a white-scattering box whose colour field is
/// (1, 0.5, 0) keeps red whole in the white furnace (albedo 1), and loses all of blue but what
/// crosses without a collision, e^(−σ) along the camera's axis-parallel rays; green lies
/// between.
#[test]
fn a_colour_field_tints_each_channel_of_the_albedo() {
    let mut volume = unit_box(8, VolumeShading { density: 2.0, color: Vec3::ONE, ..Default::default() });
    let n = 8u32.pow(3) as usize;
    let channel = |v: f32| Arc::new(VoxelGrid { values: vec![v; n], ..(*volume.density).clone() });
    volume.color = Some([channel(1.0), channel(0.5), channel(0.0)]);
    let (mean, _) = mean_beauty(&scene_with(volume), 16, 256, 1000);
    // Red: the furnace's 1, within the furnace test's 0.01. Blue: Bernoulli escapes as in the
    // Beer-Lambert test, 5σ = 0.0067.
    assert!((mean.x - 1.0).abs() < 0.01, "red {}", mean.x);
    let blue = (-2.0f32).exp();
    assert!((mean.z - blue).abs() < 5.0 * (blue * (1.0 - blue) / 65_536.0).sqrt(), "blue {} vs {blue}", mean.z);
    assert!(mean.y > mean.z + 0.2 && mean.y < mean.x - 0.1, "green {} between", mean.y);
}

#[test]
fn an_emitting_absorbing_slab_glows_as_its_closed_form() {
    // No dome: only the volume's emission. L = ε/σ · (1 − e^(−σ)) along one unit.
    let eps = Vec3::new(0.2, 0.5, 1.0);
    let sigma = 3.0f32;
    let shading = VolumeShading { density: sigma, color: Vec3::ZERO, emission: eps, ..Default::default() };
    let mut desc = scene_with(unit_box(16, shading));
    desc.lights.clear();
    let (mean, _) = mean_beauty(&desc, 16, 64, 8);
    let expected = eps / sigma * (1.0 - (-sigma).exp());
    // Tentative collisions average ε/σ̄ each: relative noise ≈ 1/sqrt(16 384 × steps); 1%.
    assert!(((mean - expected) / expected).abs().max_element() < 0.01, "{mean} vs {expected}");
}

/// The same through USD, the VDB reader, the wire and the server: `usd/volume_box.usda` is
/// box.vdb (written by OpenVDB) as an absorbing volume of density 2 under a white dome.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_vdb_box_fixture_transmits_as_beer_lambert_says_through_the_service() {
    let report = tessera_tests::render_fixture("usd/volume_box.usda", &tessera_tests::small(16, 16, 256)).await;
    let volumes = report.started.plan.iter().find(|p| p.effect == "volumes").expect("the plan lists volumes");
    assert_eq!(volumes.prims, ["/World/Box"]);
    let (mean, n) = tessera_tests::mean_where(&report.image, "beauty", 1, |_, _| true);
    let expected = (-2.0f64).exp();
    // 65 536 Bernoulli escapes: σ = 0.0013; 5σ.
    assert!(n == 256 && (mean - expected).abs() < 5.0 * (expected * (1.0 - expected) / 65_536.0).sqrt(), "{mean} vs {expected}");
}

/// A colour field read from a VDB file through USD, the wire and the server:
/// `usd/volume_tinted.usda` is the box white-scattering (albedo 1) with tinted.vdb's `Cd`,
/// (1, i/16, 0) at voxel (i, j, k). Red scatters with albedo 1 everywhere: the white furnace's
/// 1. Blue has albedo 0: only what crosses without a collision, e^(−2). Green ramps along x,
/// so the image grows greener from left to right (a grid read with its axes swapped would ramp
/// along the view and leave the columns alike).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn the_vdb_colour_field_tints_the_albedo_through_the_service() {
    // Depth 1000, as in the furnace test: red is a furnace only when no path is cut short.
    let options = tessera::remote::RenderOptions { max_depth: 1000, ..tessera_tests::small(16, 16, 256) };
    let report = tessera_tests::render_fixture("usd/volume_tinted.usda", &options).await;
    let all = |_, _| true;
    let (red, _) = tessera_tests::mean_where(&report.image, "beauty", 0, all);
    let (blue, _) = tessera_tests::mean_where(&report.image, "beauty", 2, all);
    // The furnace test's 0.01 for red; Bernoulli escapes for blue, 5σ = 0.0067.
    assert!((red - 1.0).abs() < 0.01, "red {red}");
    let expected = (-2.0f64).exp();
    assert!((blue - expected).abs() < 5.0 * (expected * (1.0 - expected) / 65_536.0).sqrt(), "blue {blue} vs {expected}");
    // Columns 0-3 see the box's x in [0.2, 0.35], columns 12-15 x in [0.65, 0.8]: green albedo
    // about 0.27 against 0.72 there, and measured 0.25 against 0.55 (2026-12-03; paths wander
    // across the ramp). Each quarter's mean has σ < 0.004 (16 384 samples of at most 1).
    let (left, _) = tessera_tests::mean_where(&report.image, "beauty", 1, |x, _| x < 4);
    let (right, _) = tessera_tests::mean_where(&report.image, "beauty", 1, |x, _| x >= 12);
    assert!(left > blue + 0.05 && right > left + 0.2 && right < red - 0.05, "green {left} left, {right} right");
}

/// Colour fields and half-float grids read as OpenVDB wrote them, voxel for voxel: tinted.vdb's
/// `Cd` (full precision) and `Cd_half` (half floats, each value exact in half precision), and
/// `density_half`, whose first leaf stores no values (OpenVDB writes no bytes for it). A colour
/// field naming a float grid, and a second colour field, are reported; the volume renders.
#[test]
fn colour_fields_and_half_float_grids_read_as_openvdb_wrote_them() {
    let dir = std::env::temp_dir().join(format!("tessera-tinted-vdb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(tessera_tests::fixture("usd/volumes/tinted.vdb"), dir.join("tinted.vdb")).unwrap();
    let asset = |name: &str| format!("def OpenVDBAsset \"{name}\" {{ asset filePath = @./tinted.vdb@\n token fieldName = \"{name}\" }}");
    let usda = format!(
        "#usda 1.0\n\
         def Volume \"Ramp\" {{ rel field:density = </Ramp/density>\n rel field:Cd = </Ramp/Cd>\n {}\n {} }}\n\
         def Volume \"Axes\" {{ rel field:density = </Axes/density_half>\n rel field:color = </Axes/Cd_half>\n {}\n {} }}\n\
         def Volume \"Wrong\" {{ rel field:density = </Wrong/density>\n rel field:color = </Wrong/density>\n {} }}\n\
         def Volume \"Twice\" {{ rel field:density = </Twice/density>\n rel field:Cd = </Twice/Cd>\n rel field:color = </Twice/Cd_half>\n {}\n {}\n {} }}\n",
        asset("density"),
        asset("Cd"),
        asset("density_half"),
        asset("Cd_half"),
        asset("density"),
        asset("density"),
        asset("Cd"),
        asset("Cd_half"),
    );
    std::fs::write(dir.join("tinted.usda"), usda).unwrap();
    let t = tessera::usd::load(&dir.join("tinted.usda")).expect("the stage loads");
    std::fs::remove_dir_all(&dir).ok();
    let volume = |path: &str| &t.volumes.iter().find(|(p, _)| p == path).unwrap_or_else(|| panic!("{path} renders")).1;
    // Every voxel of the 16³ block, x fastest, as make_vdb.py wrote it.
    let voxels = || (0..16 * 16 * 16).map(|n| (n, [n % 16, n / 16 % 16, n / 256].map(|c| c as f32)));
    let channels = |v: &VolumeDesc| {
        v.color.as_ref().expect("a colour field").clone().map(|g| {
            assert_eq!((g.origin, g.dims), (IVec3::ZERO, UVec3::splat(16)));
            g.values.clone()
        })
    };
    let [r, g, b] = channels(volume("/Ramp"));
    assert!(voxels().all(|(n, [i, _, _])| [r[n], g[n], b[n]] == [1.0, i / 16.0, 0.0]), "Cd reads as (1, i/16, 0)");
    let [r, g, b] = channels(volume("/Axes"));
    assert!(voxels().all(|(n, ijk)| [r[n], g[n], b[n]] == ijk.map(|c| c / 16.0)), "Cd_half reads as (i, j, k)/16");
    let density = &volume("/Axes").density.values;
    let first_leaf = |ijk: [f32; 3]| ijk.iter().all(|&c| c < 8.0);
    assert!(voxels().all(|(n, ijk)| density[n] == if first_leaf(ijk) { 0.0 } else { 1.0 }), "density_half");
    let warned = |needles: &[&str]| t.warnings.iter().any(|w| needles.iter().all(|n| w.contains(n)));
    assert!(warned(&["/Wrong", "field 'color' is not used", "Tree_float_5_4_3", "Tree_vec3s_5_4_3"]), "{:#?}", t.warnings);
    assert!(volume("/Wrong").color.is_none());
    assert!(warned(&["/Twice", "is not used", "already gives the colour"]), "{:#?}", t.warnings);
    assert!(volume("/Twice").color.is_some());
}

/// A scene without volumes renders the same whatever the volume machinery: the plan has no
/// volumes and the specialised path loop runs (no volume test per ray).
#[test]
fn a_scene_without_volumes_does_not_plan_them() {
    let scene = commit(&tessera_tests::load("cornell_box.usda").to_scene_desc(), &mut BlasCache::default()).expect("commits");
    assert!(!scene.plan.has(Feature::Volumes) && scene.volumes.is_empty());
    assert!(!render_core::integrator::needs_full_loop(scene.plan.features, &IntegratorSettings::default()));
}

/// A Volume whose VDB file is garbage, one naming a grid its file lacks, and one with no
/// density field are each skipped with a warning naming the prim (and the file or grid); the
/// rest of the stage renders.
#[test]
fn broken_vdb_fields_skip_their_volume_naming_it() {
    let dir = std::env::temp_dir().join(format!("tessera-broken-vdb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("garbage.vdb"), b"\x20BDV\0\0\0\0 this is not a VDB file at all").unwrap();
    std::fs::copy(tessera_tests::fixture("usd/volumes/box.vdb"), dir.join("box.vdb")).unwrap();
    let usda = r#"#usda 1.0
def Volume "Garbage" { rel field:density = </Garbage/d>
    def OpenVDBAsset "d" { asset filePath = @./garbage.vdb@
        token fieldName = "density" } }
def Volume "NoSuchGrid" { rel field:density = </NoSuchGrid/d>
    def OpenVDBAsset "d" { asset filePath = @./box.vdb@
        token fieldName = "smoke" } }
def Volume "NoDensity" { rel field:color = </NoDensity/c>
    def OpenVDBAsset "c" { asset filePath = @./box.vdb@
        token fieldName = "density" } }
def Volume "Good" { rel field:density = </Good/d>
    def OpenVDBAsset "d" { asset filePath = @./box.vdb@
        token fieldName = "density" } }
def Sphere "Ball" {}
"#;
    std::fs::write(dir.join("broken.usda"), usda).unwrap();
    let t = tessera::usd::load(&dir.join("broken.usda")).expect("the stage loads");
    std::fs::remove_dir_all(&dir).ok();
    let warned = |needles: &[&str]| t.warnings.iter().any(|w| needles.iter().all(|n| w.contains(n)));
    assert!(warned(&["/Garbage", "garbage.vdb", "skipped"]), "{:#?}", t.warnings);
    assert!(warned(&["/NoSuchGrid", "no grid 'smoke'", "density"]), "{:#?}", t.warnings);
    assert!(warned(&["/NoDensity", "field 'color' is not used", "Tree_float_5_4_3"]), "{:#?}", t.warnings);
    assert!(warned(&["/NoDensity", "no field:density"]), "{:#?}", t.warnings);
    let volumes: Vec<&str> = t.volumes.iter().map(|(p, _)| p.as_str()).collect();
    assert_eq!(volumes, ["/Good"]);
    assert_eq!(t.volumes[0].1.density.values.len(), 16 * 16 * 16);
    assert!(t.meshes.iter().any(|(p, _)| p == "/Ball"), "the rest renders");
}

/// An absorbing box sliding one unit either way over the shutter: each column of the image
/// sees the box's transmittance averaged over the shutter, the closed form of a streak.
#[test]
fn a_moving_volume_blurs_into_the_streak_of_its_transmittance() {
    let (sigma, n) = (2.0f32, 16u32);
    let mut volume = unit_box(n, VolumeShading { density: sigma, color: Vec3::ZERO, ..Default::default() });
    volume.motion = [-1.0, 0.0, 1.0].map(|dx| Affine3A::from_translation(Vec3::new(dx, 0.0, 0.0)) * volume.index_to_world).to_vec();
    let mut desc = scene_with(volume);
    // Four units wide (x from −1.5 to 2.5), one high (the box's rows).
    let camera = desc.cameras.get_mut("/Cam").unwrap();
    (camera.horizontal_aperture, camera.vertical_aperture) = (40.0, 10.0);
    let scene = commit(&desc, &mut BlasCache::default()).expect("commits");
    assert!(scene.plan.has(Feature::MotionBlur) && scene.plan.has(Feature::Volumes), "the plan lists the moving volume");
    let (w, h, spp) = (64u32, 16u32, 1024u32);
    let camera = Camera::new(&scene.camera("/Cam").expect("camera"), w, h);
    let settings = RenderSettings {
        width: w,
        height: h,
        spp,
        integrator: IntegratorSettings { max_depth: 8, ..Default::default() },
        ..Default::default()
    };
    let (fb, _) = render_to_framebuffer(&scene, &camera, &settings);
    let px = &fb.layers[&Aov::Beauty];
    // The density across x: 1 inside, ramping linearly over the voxel around each face (the
    // trilinear reading of voxel centres, its value 0 a voxel outside).
    let half = 0.5 / n as f64;
    let profile = |x: f64| ((x + half) / (2.0 * half)).clamp(0.0, 1.0).min(((1.0 + half - x) / (2.0 * half)).clamp(0.0, 1.0));
    // Its transmittance averaged over the shutter: the box's left face moves from −1 to 1.
    let streak = |x: f64| {
        let steps = 4000;
        (0..steps).map(|i| -1.0 + 2.0 * (i as f64 + 0.5) / steps as f64).map(|s| (-(sigma as f64) * profile(x - s)).exp()).sum::<f64>()
            / steps as f64
    };
    // Rows 2 to 13 lie inside the box's y ramps, where every ray crosses one unit along z.
    let rows = 2..h - 2;
    let mut worst: f64 = 0.0;
    for x in 0..w {
        let seen = rows.clone().map(|y| px[((y * w + x) * 4) as usize] as f64).sum::<f64>() / rows.len() as f64;
        let expected = streak(-1.5 + 4.0 * (x as f64 + 0.5) / w as f64);
        // Each sample escapes or not (a Bernoulli trial of mean `expected`, time included);
        // the pixel footprint (1/16 unit) adds a little where the streak has its slope.
        let sd = (expected * (1.0 - expected) / (rows.len() as u32 * spp) as f64).sqrt();
        worst = worst.max((seen - expected).abs() / (sd + 1e-3));
    }
    // 5 noise deviations (plus 1e-3 for the footprint) over 64 columns.
    assert!(worst < 5.0, "a column strays {worst:.2} deviations from the streak");
}

/// A Volume whose transform is animated carries its index-to-world placement at each motion
/// sample (the prim's world, then the VDB's transform), and `inspect --json` lists its motion
/// as usd-core computes it.
#[test]
fn a_volume_prims_motion_is_read_over_the_shutter() {
    let dir = std::env::temp_dir().join(format!("tessera-moving-vdb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::copy(tessera_tests::fixture("usd/volumes/box.vdb"), dir.join("box.vdb")).unwrap();
    let usda = format!(
        r#"#usda 1.0
(
    startTimeCode = 0
    endTimeCode = 1
)
{}
def Volume "Drift"
{{
    rel field:density = </Drift/d>
    double3 xformOp:translate.timeSamples = {{ 0: (-1, 0, 0), 1: (1, 0, 0) }}
    uniform token[] xformOpOrder = ["xformOp:translate"]
    def OpenVDBAsset "d"
    {{
        asset filePath = @./box.vdb@
        token fieldName = "density"
    }}
}}
"#,
        tessera_tests::ortho_camera_and_dome_usda(40.0, "double shutter:open = 0\n    double shutter:close = 1")
    );
    let file = dir.join("drift.usda");
    std::fs::write(&file, usda).unwrap();
    let t = tessera::usd::load(&file).expect("the stage loads");
    let ours = tessera::commands::inspect::inspect(&file, Default::default()).expect("inspects");
    let theirs = tessera_tests::usd_core_reads(&file, None);
    std::fs::remove_dir_all(&dir).ok();
    let (_, v) = &t.volumes[0];
    assert_eq!(v.motion.len(), tessera::usd::DEFAULT_MOTION_SAMPLES);
    // The frame (time 0, shutter open) and each sample differ by the prim's slide alone.
    for (k, m) in v.motion.iter().enumerate() {
        let slide = Affine3A::from_translation(Vec3::new(-1.0 + 2.0 * k as f32 / 4.0, 0.0, 0.0));
        let expected = slide * Affine3A::from_translation(Vec3::new(1.0, 0.0, 0.0)) * v.index_to_world;
        assert!(m.abs_diff_eq(expected, 1e-6), "sample {k}: {m:?} vs {expected:?}");
    }
    let motion = |json: &serde_json::Value| -> Vec<f64> {
        json["volumes"]["/Drift"]["motion"]
            .as_array()
            .expect("motion listed")
            .iter()
            .flat_map(|m| m.as_array().unwrap().iter().map(|x| x.as_f64().unwrap()))
            .collect()
    };
    let (a, b) = (motion(&ours), motion(&theirs));
    assert!(a.len() == 5 * 16 && a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6), "ours {a:?}\nusd-core {b:?}");
}

/// A field file that is not a VDB, a VDB older than the reader reads (file version 215 here,
/// stamped on tinted.vdb) or one whose grid transform it does not know is a warning naming the
/// field and why, and the rest renders: the reader had stopped at `todo!`s for versions
/// 213-217, took any file for a VDB, and panicked on other transforms.
#[test]
fn a_field_file_that_is_no_vdb_or_too_old_is_a_warning_naming_why() {
    let dir = std::env::temp_dir().join(format!("tessera-bad-vdb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mut old = std::fs::read(tessera_tests::fixture("usd/volumes/tinted.vdb")).unwrap();
    old[8..12].copy_from_slice(&215u32.to_le_bytes());
    std::fs::write(dir.join("old.vdb"), old).unwrap();
    std::fs::write(dir.join("text.vdb"), "a text file named like a VDB, longer than its header").unwrap();
    // A grid transform the reader does not know (OpenVDB's affine, unitary, translation and
    // frustum maps): every map name in the file renamed, at the same length.
    let mut renamed = std::fs::read(tessera_tests::fixture("usd/volumes/tinted.vdb")).unwrap();
    let (map, unknown) = (b"UniformScaleTranslateMap", b"UniformScaleTranslateMaq");
    for at in 0..renamed.len() - map.len() {
        if renamed[at..].starts_with(map) {
            renamed[at..at + map.len()].copy_from_slice(unknown);
        }
    }
    std::fs::write(dir.join("unknown_map.vdb"), renamed).unwrap();
    let volume = |name: &str, file: &str| {
        format!(
            "def Volume \"{name}\" {{ rel field:density = </{name}/density>\n def OpenVDBAsset \"density\" {{ asset filePath = @./{file}@\n token fieldName = \"density\" }} }}\n"
        )
    };
    let volumes = [volume("Old", "old.vdb"), volume("Text", "text.vdb"), volume("Affine", "unknown_map.vdb")];
    let usda = format!("#usda 1.0\n{}def Sphere \"Ball\" {{}}\n", volumes.concat());
    std::fs::write(dir.join("bad.usda"), usda).unwrap();
    let t = tessera::usd::load(&dir.join("bad.usda")).expect("the stage loads");
    std::fs::remove_dir_all(&dir).ok();
    let warned = |needles: &[&str]| t.warnings.iter().any(|w| needles.iter().all(|n| w.contains(n)));
    assert!(warned(&["/Old/density", "version 215", "218"]), "{:#?}", t.warnings);
    assert!(warned(&["/Text/density", "Not a VDB file"]), "{:#?}", t.warnings);
    assert!(warned(&["/Affine/density", "Unsupported grid transform UniformScaleTranslateMaq"]), "{:#?}", t.warnings);
    assert!(t.volumes.is_empty() && !t.meshes.is_empty(), "the volumes are skipped, the sphere renders");
}

/// A grid whose VDB transform turns it (OpenVDB's `AffineMap`, rotated.vdb) lands where the
/// same grid under a scale-translate map lands when the prim's USD transform turns it instead:
/// the two index-to-world maps agree, and so do their voxels.
#[test]
fn an_affine_vdb_transform_places_the_grid_as_a_usd_transform_does() {
    let dir = std::env::temp_dir().join(format!("tessera-affine-vdb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    for name in ["rotated.vdb", "box.vdb"] {
        std::fs::copy(tessera_tests::fixture(&format!("usd/volumes/{name}")), dir.join(name)).unwrap();
    }
    let usda = "#usda 1.0\n\
        def Volume \"InFile\" { rel field:density = </InFile/density>\n\
         def OpenVDBAsset \"density\" { asset filePath = @./rotated.vdb@\n token fieldName = \"density\" } }\n\
        def Volume \"InStage\" { rel field:density = </InStage/density>\n\
         double3 xformOp:translate = (1, 0, 0)\n float xformOp:rotateZ = 90\n\
         uniform token[] xformOpOrder = [\"xformOp:translate\", \"xformOp:rotateZ\"]\n\
         def OpenVDBAsset \"density\" { asset filePath = @./box.vdb@\n token fieldName = \"density\" } }\n";
    std::fs::write(dir.join("turned.usda"), usda).unwrap();
    let t = tessera::usd::load(&dir.join("turned.usda")).expect("the stage loads");
    std::fs::remove_dir_all(&dir).ok();
    assert!(t.warnings.is_empty(), "{:#?}", t.warnings);
    let volume = |path: &str| &t.volumes.iter().find(|(p, _)| p == path).unwrap_or_else(|| panic!("{path} renders")).1;
    let (in_file, in_stage) = (volume("/InFile"), volume("/InStage"));
    // Index (i, j, k) at (1 - (j + 0.5)/16, (i + 0.5)/16, (k + 0.5)/16), as make_vdb.py wrote it;
    // 1e-6 is the f32 rounding of a quarter turn's cosine.
    let voxel = in_file.index_to_world.transform_point3(Vec3::new(2.0, 3.0, 4.0));
    assert!(voxel.abs_diff_eq(Vec3::new(1.0 - 3.5 / 16.0, 2.5 / 16.0, 4.5 / 16.0), 1e-6), "{voxel}");
    assert!(
        in_file.index_to_world.abs_diff_eq(in_stage.index_to_world, 1e-6),
        "{:?} vs {:?}",
        in_file.index_to_world,
        in_stage.index_to_world
    );
    assert_eq!((in_file.density.origin, in_file.density.dims), (in_stage.density.origin, in_stage.density.dims));
    assert_eq!(in_file.density.values, in_stage.density.values);
}
