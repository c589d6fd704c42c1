//! The layered-material front-ends (`tessera:Metal`, `Refractive`, `SolidDielectric`,
//! `Fabric`, `Layer`) in whole renders: read from USD, planned, and energy-safe.

use tessera_tests::*;

/// Mean red value over the furnace sphere.
async fn furnace_mean(rel: &str) -> f64 {
    furnace_sphere_mean(rel, true).await
}

/// White metal over a white plastic with a clearcoat and a sheen (mask 0.5), and a closed
/// thin sheet, in the unit white furnace: no energy gain (the background is 1); the losses
/// are the coats' min rule and the thin sheet's grazing angles (docs/materials.md).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn layered_coated_and_thin_materials_never_gain_energy_in_the_furnace() {
    let layered = furnace_mean("materials/furnace_layered.usda").await;
    assert!(layered <= 1.02 && layered > 0.85, "layered: {layered}");
    let thin = furnace_mean("materials/furnace_thin.usda").await;
    assert!(thin <= 1.02 && thin > 0.85, "thin sheet: {thin}");
}

/// The showcase reads every native shader without a warning, and the plan names each effect
/// with the material that calls for it.
#[test]
fn showcase_plan_lists_every_effect_by_material() {
    let plan = tessera::commands::render::explain_plan(&fixture("materials/showcase.usda"), None).unwrap();
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
    let plan = tessera::commands::render::explain_plan(&fixture("materials/furnace_subsurface.usda"), None).unwrap();
    assert!(plan.contains("+ subsurface") && plan.contains("/World/Looks/Skin"), "{plan}");
}
