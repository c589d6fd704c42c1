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

/// Exit statuses a scheduler can act on (`tessera::exit`): 2 when retrying will not help (a
/// scene that is not there or does not parse, `--strict` with warnings), 3 when it may (no
/// server at the URL), 0 for a render that skipped a malformed prim with a warning.
#[test]
fn exit_statuses_say_whether_a_retry_can_help() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::env::temp_dir().join(format!("tessera-cli-exit-{}", std::process::id()));
    let status = |scene: &str, extra: &[&str]| {
        let run = Command::new(env!("CARGO_BIN_EXE_tessera"))
            .args(["render", "--res", "8x8", "--spp", "1", "-o"])
            .arg(out.join("frame.exr"))
            .args(extra)
            .arg(root.join(scene))
            .output()
            .expect("the CLI runs");
        (run.status.code(), String::from_utf8_lossy(&run.stderr).to_string())
    };
    assert_eq!(status("fixtures/bad/does_not_exist.usda", &[]).0, Some(2));
    assert_eq!(status("fixtures/bad/malformed.usda", &[]).0, Some(2));
    let (code, stderr) = status("fixtures/bad/malformed_prims.usda", &[]);
    assert_eq!(code, Some(0), "{stderr}");
    assert!(stderr.contains("/World/NoPoints") && stderr.contains("the prim is skipped"), "{stderr}");
    assert_eq!(status("fixtures/bad/malformed_prims.usda", &["--strict"]).0, Some(2));
    // Nothing listens on port 1 of loopback.
    let (code, stderr) = status("fixtures/cornell_box.usda", &["--server", "http://127.0.0.1:1"]);
    assert_eq!(code, Some(3), "{stderr}");
    let left: Vec<_> = std::fs::read_dir(&out).map(|d| d.map(|e| e.unwrap().file_name()).collect()).unwrap_or_default();
    assert_eq!(
        left.iter().filter(|n| n.to_string_lossy() != "frame.exr" && n.to_string_lossy() != "frame.png").count(),
        0,
        "no partial files: {left:?}"
    );
    std::fs::remove_dir_all(&out).ok();
}

/// A frame range in one process, as a farm scheduler runs it: each frame evaluated at its
/// time (sent as the changes since the frame before, and equal to the frame rendered alone)
/// and written to the name its pattern gives, `ALF_PROGRESS` lines to 100%, and
/// `--skip-existing` skipping exactly the frames already rendered with the same settings.
#[test]
fn frame_ranges_name_each_frame_report_progress_and_skip_what_exists() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::env::temp_dir().join(format!("tessera-cli-frames-{}", std::process::id()));
    let render = |extra: &[&str]| {
        let run = Command::new(env!("CARGO_BIN_EXE_tessera"))
            .args(["render", "--res", "12x8", "--frames", "1-9x4", "-o"])
            .arg(out.join("anim.####.exr"))
            .args(extra)
            .arg(root.join("fixtures/usd/animated.usda"))
            .output()
            .expect("the CLI runs");
        assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
        (String::from_utf8_lossy(&run.stdout).to_string(), String::from_utf8_lossy(&run.stderr).to_string())
    };
    let (stdout, _) = render(&["--spp", "1", "--alf-progress"]);
    let frames = ["anim.0001.exr", "anim.0005.exr", "anim.0009.exr"].map(|f| out.join(f));
    assert!(frames.iter().all(|f| f.is_file()), "{:?}", std::fs::read_dir(&out).unwrap().collect::<Vec<_>>());
    let alf: Vec<u32> = stdout.lines().filter_map(|l| l.strip_prefix("ALF_PROGRESS ")?.strip_suffix('%')?.parse().ok()).collect();
    assert!(alf.windows(2).all(|w| w[0] < w[1]) && alf.last() == Some(&100) && alf.len() >= 3, "{stdout}");
    let beauty = |f: &std::path::Path| tessera::output::read_exr(f).unwrap().layers["beauty"].1.clone();
    assert_ne!(beauty(&frames[0]), beauty(&frames[2]), "each frame at its own time");
    // Frame 5 of the range (synced as changes since frame 1) is frame 5 rendered alone.
    let alone = out.join("alone.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(["render", "--res", "12x8", "--spp", "1", "--frame", "5", "-o"])
        .arg(&alone)
        .arg(root.join("fixtures/usd/animated.usda"))
        .output()
        .unwrap();
    assert!(run.status.success());
    assert_eq!(beauty(&alone), beauty(&frames[1]), "bit-identical to a render of the frame alone");
    for f in ["alone.exr", "alone.png"] {
        std::fs::remove_file(out.join(f)).unwrap();
    }
    let modified = |f: &std::path::Path| std::fs::metadata(f).unwrap().modified().unwrap();
    let before: Vec<_> = frames.iter().map(|f| modified(f)).collect();
    let (_, stderr) = render(&["--spp", "1", "--skip-existing"]);
    assert_eq!(stderr.matches("already rendered with these settings; skipped").count(), 3, "{stderr}");
    assert_eq!(frames.iter().map(|f| modified(f)).collect::<Vec<_>>(), before, "nothing rewritten");
    let (_, stderr) = render(&["--spp", "2", "--skip-existing"]);
    assert!(!stderr.contains("skipped"), "other settings render again: {stderr}");
    std::fs::remove_dir_all(&out).ok();
}

/// Without Open Image Denoise, `--denoise` fails before rendering with the install hint, as
/// bad input (exit status 2), and writes nothing.
#[test]
fn denoise_without_the_library_says_how_to_install_it() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let out = std::env::temp_dir().join(format!("tessera-cli-denoise-{}", std::process::id()));
    let run = Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(["render", "--res", "8x8", "--spp", "1", "--denoise", "-o"])
        .arg(out.join("frame.exr"))
        .arg(root.join("fixtures/cornell_box.usda"))
        .env("TESSERA_OIDN_LIB", "/nonexistent/libOpenImageDenoise.so")
        .output()
        .expect("the CLI runs");
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert_eq!(run.status.code(), Some(2), "{stderr}");
    assert!(stderr.contains("pip install pyoidn"), "{stderr}");
    assert!(!out.join("frame.exr").exists(), "nothing written");
    std::fs::remove_dir_all(&out).ok();
}
