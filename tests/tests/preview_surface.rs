//! UsdPreviewSurface, one input per fixture (`fixtures/materials/preview/`), each checked
//! against what the specification says it shows. The sphere (radius 1, seen from 4 units with a
//! 50 mm lens on a 36 mm aperture) spans 0.717 of the half-frame, 22.9 pixels of a 64-pixel
//! frame; tests read discs and rings of pixels around its centre.

use tessera::output::Image;
use tessera_tests::*;

const SIZE: u32 = 64;
const SPHERE_RADIUS_PX: f64 = 0.2582 / 0.36 * 32.0;

/// Mean of `aov` over the pixels whose centres lie between `r0` and `r1` pixels from the
/// frame's centre, per channel.
fn ring(image: &Image, aov: &str, r0: f64, r1: f64) -> [f64; 4] {
    let c = SIZE as f64 / 2.0;
    let mut sum = [0.0; 4];
    let mut n = 0.0;
    for y in 0..SIZE {
        for x in 0..SIZE {
            let r = ((x as f64 + 0.5 - c).powi(2) + (y as f64 + 0.5 - c).powi(2)).sqrt();
            if r >= r0 && r < r1 {
                let p = image.pixel(aov, x, y);
                (0..4).for_each(|k| sum[k] += p[k] as f64);
                n += 1.0;
            }
        }
    }
    assert!(n > 0.0);
    sum.map(|s| s / n)
}

async fn render(name: &str, spp: u32) -> Image {
    let report = render_fixture(&format!("materials/preview/{name}"), &small(SIZE, SIZE, spp)).await;
    assert_all_finite(&report.image);
    assert!(report.started.warnings.is_empty(), "{name}: {:?}", report.started.warnings);
    report.image
}

/// `metallic` 1, roughness 0: a mirror whose normal-incidence reflectance is `diffuseColor`, so
/// head-on it shows the unit dome as exactly that gold.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn metallic_gold_reflects_its_colour_head_on() {
    let img = render("gold.usda", 16).await;
    let c = ring(&img, "beauty", 0.0, 3.0);
    for (k, want) in [0.944, 0.776, 0.373].into_iter().enumerate() {
        assert!((c[k] - want).abs() < 0.015 * want, "channel {k}: {} vs {want}", c[k]);
    }
}

/// The specular workflow: `specularColor` head-on, going to white towards grazing angles.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn specular_workflow_reflects_specular_colour_head_on_and_white_at_the_rim() {
    let img = render("specular_workflow.usda", 16).await;
    let centre = ring(&img, "beauty", 0.0, 3.0);
    for (k, want) in [0.6, 0.3, 0.1].into_iter().enumerate() {
        assert!((centre[k] - want).abs() < 0.02 * want, "channel {k}: {} vs {want}", centre[k]);
    }
    let rim = ring(&img, "beauty", SPHERE_RADIUS_PX - 2.5, SPHERE_RADIUS_PX - 0.5);
    assert!(rim[2] / rim[0] > 1.5 * centre[2] / centre[0], "rim {rim:?} is no whiter than the centre {centre:?}");
}

/// A clearcoat adds a highlight (a smooth coat over a rough grey shows a small light's mirror
/// image, many times brighter than the grey's own broad highlight) and no energy: clearcoated
/// white stays at or below the unit furnace: 0.995 measured 2026-12-08 (the diffuse
/// renormalised under the coat; the specular layer beneath keeps the min rule), bounded 2%
/// below; 0.959 by the min rule alone, which fails it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn clearcoat_adds_a_highlight_but_no_energy() {
    let furnace = furnace_sphere_mean("materials/preview/clearcoat_furnace.usda", true).await;
    println!("clearcoated white in the furnace: {furnace}");
    assert!(furnace <= 1.01 && furnace > 0.975, "clearcoated white in the furnace: {furnace}");
    let peak = |img: &Image| (0..SIZE * SIZE).map(|i| img.pixel("beauty", i % SIZE, i / SIZE)[1]).fold(0.0f32, f32::max);
    let (coated, plain) = (render("clearcoat_lit.usda", 64).await, render("plain_lit.usda", 64).await);
    println!("peak with clearcoat {}, without {}", peak(&coated), peak(&plain));
    assert!(peak(&coated) > 3.0 * peak(&plain), "peak with clearcoat {} vs without {}", peak(&coated), peak(&plain));
}

/// `opacity` below a positive `opacityThreshold` cuts the surface out: nothing is drawn and the
/// dome shows through unchanged.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn opacity_below_its_threshold_cuts_the_surface_out() {
    let img = render("cutout.usda", 4).await;
    let all = ring(&img, "beauty", 0.0, 100.0);
    assert_eq!(all[3], 0.0, "alpha");
    assert!((all[0] - 1.0).abs() < 1e-6 && (all[1] - 1.0).abs() < 1e-6, "{all:?}");
}

/// `opacityMode` `presence`: a 30%-present surface lets 70% of rays through unbent. A camera
/// ray through the sphere's middle crosses two such surfaces, so 0.7² = 0.49 of rays reach the
/// unit dome (green 0.49: the red sphere reflects no green) and alpha is 0.51.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn presence_lets_its_share_of_rays_through_unbent() {
    let img = render("presence.usda", 64).await;
    let inside = ring(&img, "beauty", 0.0, SPHERE_RADIUS_PX - 5.0);
    assert!((inside[1] - 0.49).abs() < 0.02, "green through the sphere {}", inside[1]);
    assert!((inside[3] - 0.51).abs() < 0.02, "alpha over the sphere {}", inside[3]);
    let outside = ring(&img, "beauty", SPHERE_RADIUS_PX + 2.0, 100.0);
    assert_eq!(outside[3], 0.0);
    let plan = tessera::commands::render::explain_plan(&fixture("materials/preview/presence.usda"), Default::default()).unwrap();
    assert!(plan.contains("+ partial-presence") && !plan.contains("  ! "), "{plan}");
}

/// `emissiveColor` in UsdLux radiance units: with no other light and a black, specular-free
/// surface, the sphere's pixels are exactly its emission.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn emissive_colour_is_the_radiance_the_camera_sees() {
    let img = render("emission.usda", 4).await;
    let c = ring(&img, "beauty", 0.0, SPHERE_RADIUS_PX - 3.0);
    for (k, want) in [2.0, 1.0, 0.5].into_iter().enumerate() {
        assert!((c[k] - want).abs() < 1e-3 * want, "channel {k}: {} vs {want}", c[k]);
    }
}
