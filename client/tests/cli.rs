//! The CLI as a farm runs it: stderr piped, so no progress bar. The render plan and every
//! warning must still reach the log.

use std::process::Command;

#[test]
fn a_piped_render_still_prints_the_plan_and_the_warnings() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::env::temp_dir().join(format!("tessera-cli-{}", std::process::id()));
    let exr = out.join("smooth.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(["render", "--res", "16x12", "--spp", "1", "-o"])
        .arg(&exr)
        .arg(root.join("fixtures/materials/subsurface_smooth.usda"))
        .output()
        .expect("the CLI runs");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "{stderr}");
    assert!(stderr.contains("render plan:") && stderr.contains("+ subsurface"), "{stderr}");
    assert!(stderr.contains("warning: /World/Looks/Skin: subsurface behind a smooth boundary"), "{stderr}");
    assert!(exr.is_file(), "no {}", exr.display());
    std::fs::remove_dir_all(&out).ok();
}
