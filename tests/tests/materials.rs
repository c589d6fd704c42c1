//! The layered-material front-ends (`tessera:Metal`, `Refractive`, `SolidDielectric`,
//! `Fabric`, `Layer`) in whole renders: read from USD, planned, and energy-safe.

use tessera_tests::*;

/// Mean red value over the furnace sphere.
async fn furnace_mean(rel: &str) -> f64 {
    furnace_sphere_mean(rel, true).await
}

/// White metal over a white plastic with a clearcoat and a sheen (mask 0.5), and a closed
/// thin sheet, in the unit white furnace: no energy gain (the background is 1); the losses
/// are the coats' min rule and the thin sheet's grazing angles (docs/materials.md). Measured
/// 2026-12-02: layered 0.955, thin 0.983 (fixed seed); the lower bounds sit 2% below, the
/// sphere mean's sampling noise at this spp being well under 1%, so a 5% loss fails.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn layered_coated_and_thin_materials_never_gain_energy_in_the_furnace() {
    let layered = furnace_mean("materials/furnace_layered.usda").await;
    println!("layered in the furnace: {layered}");
    assert!(layered <= 1.01 && layered > 0.935, "layered: {layered}");
    let thin = furnace_mean("materials/furnace_thin.usda").await;
    println!("thin sheet in the furnace: {thin}");
    assert!(thin <= 1.01 && thin > 0.963, "thin sheet: {thin}");
}

/// The showcase reads every native shader without a warning, and the plan names each effect
/// with the material that calls for it.
#[test]
fn showcase_plan_lists_every_effect_by_material() {
    let plan = tessera::commands::render::explain_plan(&fixture("materials/showcase.usda"), Default::default()).unwrap();
    assert!(!plan.contains("  ! "), "warnings: {plan}");
    for (effect, material) in [
        ("metal", "/World/Looks/Gold"),
        ("transmission", "/World/Looks/Glass"),
        ("thin-transmission", "/World/Looks/Pane"),
        ("clearcoat", "/World/Looks/Varnish"),
        ("sheen", "/World/Looks/Velvet"),
        ("fabric", "/World/Looks/Silk"),
        ("diffuse", "/World/Looks/DirtyGlass"),
    ] {
        let line = plan.lines().position(|l| l.contains(&format!("+ {effect} "))).unwrap_or_else(|| panic!("no {effect}: {plan}"));
        let prims = plan.lines().nth(line + 1).unwrap_or_default();
        assert!(prims.contains(material), "{effect} should name {material}: {plan}");
    }
    // The dirt's IOR stays with the dirt: the glass under it is still listed as refracting.
    let transmission = plan.lines().skip_while(|l| !l.contains("+ transmission ")).nth(1).unwrap();
    assert!(transmission.contains("/World/Looks/DirtyGlass"), "{plan}");
}

/// Subsurface scattering with a tiny mean free path behaves like its diffuse counterpart: a
/// sphere whose medium shows colour C = 0.5 (by the van de Hulst inversion) renders 0.5 in the
/// white furnace, as a Lambertian sphere of albedo 0.5 does, within the formula's accuracy.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn subsurface_with_a_tiny_mean_free_path_looks_like_its_diffuse_colour() {
    let mean = furnace_mean("materials/furnace_subsurface.usda").await;
    println!("subsurface sphere, C = 0.5, mfp = radius/1000: furnace mean {mean}");
    assert!((mean - 0.5).abs() < 0.03, "subsurface sphere renders {mean}, its diffuse counterpart 0.5");
    let plan = tessera::commands::render::explain_plan(&fixture("materials/furnace_subsurface.usda"), Default::default()).unwrap();
    assert!(plan.contains("+ subsurface") && plan.contains("/World/Looks/Skin"), "{plan}");
}

/// Relative RMS difference of the beauty of two renders of the same size.
fn relative_rms(a: &tessera::output::Image, b: &tessera::output::Image) -> f64 {
    let (mut diff, mut norm) = (0.0, 0.0);
    for y in 0..a.height {
        for x in 0..a.width {
            let (p, q) = (a.pixel("beauty", x, y), b.pixel("beauty", x, y));
            for c in 0..3 {
                diff += ((p[c] - q[c]) as f64).powi(2);
                norm += (p[c] as f64).powi(2);
            }
        }
    }
    (diff / norm.max(1e-30)).sqrt()
}

/// Glitter flakes stick to their object (Xie & Lanz 2017, "Physically Based Shading at DreamWorks Animation", section 3.5): the sphere, its light and
/// the camera moved together by a fraction of a flake cell render the same image, pixel for
/// pixel up to rounding, far closer than two renders of one scene with different seeds.
/// Flakes placed in world space would all have moved across the sphere.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn glitter_flakes_stay_on_a_moving_object() {
    let opts = small(128, 128, 16);
    let here = render_fixture("materials/glitter.usda", &opts).await.image;
    let moved = render_fixture("materials/glitter_moved.usda", &opts).await.image;
    let reseeded = render_fixture("materials/glitter.usda", &tessera::remote::RenderOptions { seed: 7, ..opts.clone() }).await.image;
    assert_all_finite(&here);
    let (motion, noise) = (relative_rms(&here, &moved), relative_rms(&here, &reseeded));
    println!("glitter moved with its rig: relative RMS {motion:.4}; another seed: {noise:.4}");
    assert!(motion < 0.25 * noise, "moving the rig changed the image by {motion}, more than a quarter of the noise {noise}");
}

/// White flakes over a white base in the unit furnace: no energy gain, and the plan names the
/// glitter with its material; the fixture reads without a warning. The flakes lose what they
/// reflect below the surface and what the binder masks (single scattering, as in the slides'
/// model: nothing bounces between flakes): with a spread of 0.5 over 80% coverage the sphere
/// renders 0.72 (0.723 measured 2026-12-02); the bound sits 0.02 below it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn glitter_never_gains_energy_and_is_planned() {
    let mean = furnace_mean("materials/furnace_glitter.usda").await;
    println!("white glitter over white in the furnace: mean {mean}");
    assert!(mean <= 1.01 && mean > 0.70, "glitter furnace: {mean}");
    let plan = tessera::commands::render::explain_plan(&fixture("materials/glitter.usda"), Default::default()).unwrap();
    assert!(!plan.contains("  ! "), "warnings: {plan}");
    let line = plan.lines().position(|l| l.contains("+ glitter ")).unwrap_or_else(|| panic!("no glitter: {plan}"));
    assert!(plan.lines().nth(line + 1).unwrap_or_default().contains("/World/Looks/Glitter"), "{plan}");
}
