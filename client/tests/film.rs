//! Exact films through the CLI: slices of a frame's samples merge to the whole render, and a
//! render killed with SIGKILL resumes from its checkpoint to the same pixels, bit for bit.

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

mod common;
use common::{pixels, root, scratch};

/// `tessera render` of the Cornell box at 32x32 with two extra AOVs (one of them from the
/// optional light-path buffer) and `extra` arguments.
fn render(extra: &[&str]) -> std::process::Output {
    let run = Command::new(env!("CARGO_BIN_EXE_tessera"))
        .args(["render", "--res", "32x32", "--aov", "albedo,diffuse_direct"])
        .args(extra)
        .arg(root().join("fixtures/cornell_box.usda"))
        .output()
        .expect("the CLI runs");
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    run
}

/// Three slices of unequal length (one of two passes), rendered in separate processes and
/// merged in shuffled order, give the single render's pixels in every layer.
#[test]
fn slices_merge_to_the_whole_render_bit_for_bit() {
    let dir = scratch("film", "slices");
    let whole = dir.join("whole.exr");
    render(&["--spp", "256", "-o", whole.to_str().unwrap()]);
    let mut parts = Vec::new();
    for range in ["128-256", "0-64", "64-128"] {
        let part = dir.join(format!("part.{range}"));
        render(&["--spp", "256", "--sample-range", range, "--partial", part.to_str().unwrap()]);
        parts.push(part);
    }
    let merged = dir.join("merged.exr");
    let run = Command::new(env!("CARGO_BIN_EXE_tessera")).arg("merge").args(&parts).arg("-o").arg(&merged).output().unwrap();
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let (a, b) = (pixels(&whole), pixels(&merged));
    assert_eq!(a.iter().map(|l| &l.0).collect::<Vec<_>>(), b.iter().map(|l| &l.0).collect::<Vec<_>>());
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "layer {name} differs");
    }
    let attr = |p: &Path, k| tessera::output::exr_attribute(p, k);
    assert_eq!(attr(&merged, "sppAsked"), Some("256".into()));
    assert_eq!(attr(&merged, "settingsHash"), attr(&whole, "settingsHash"));
    assert_eq!(attr(&merged, "mean_spp"), attr(&whole, "mean_spp"));
    std::fs::remove_dir_all(&dir).ok();
}

/// Slices that do not cover samples 0 to their end, or that do not start a pass, are refused
/// with a message saying which.
#[test]
fn gaps_and_misaligned_slices_are_refused() {
    let dir = scratch("film", "gaps");
    let part = |range: &str| {
        let p = dir.join(format!("part.{range}"));
        (
            Command::new(env!("CARGO_BIN_EXE_tessera"))
                .args(["render", "--res", "8x8", "--spp", "128", "--sample-range", range, "--partial"])
                .arg(&p)
                .arg(root().join("fixtures/cornell_box.usda"))
                .output()
                .unwrap(),
            p,
        )
    };
    let (run, _) = part("3-64");
    assert_eq!(run.status.code(), Some(2), "a bad setting is not worth retrying");
    assert!(String::from_utf8_lossy(&run.stderr).contains("first_sample"), "{}", String::from_utf8_lossy(&run.stderr));
    let (_, a) = part("0-32");
    let (_, b) = part("64-128");
    let merge = Command::new(env!("CARGO_BIN_EXE_tessera")).arg("merge").arg(&a).arg(&b).arg("-o").arg(dir.join("m.exr")).output().unwrap();
    assert!(!merge.status.success());
    assert!(String::from_utf8_lossy(&merge.stderr).contains("do not follow"), "{}", String::from_utf8_lossy(&merge.stderr));
    std::fs::remove_dir_all(&dir).ok();
}

/// The checkpoint's range end, read from its header (the first checkpoint proves the render
/// got somewhere before the kill).
fn checkpoint_end(path: &Path) -> Option<u32> {
    tessera::film::ExactFilm::load(path).ok().map(|f| f.range.end)
}

/// A render checkpointing at every pass is killed (SIGKILL) at three different points, each
/// time resumed, and killed again; the last resume runs to the end. The EXR equals the
/// uninterrupted render's in every layer, and no partial file is ever left at the final path.
#[test]
fn a_killed_render_resumes_bit_for_bit() {
    let dir = scratch("film", "resume");
    let clean = dir.join("clean.exr");
    render(&["--spp", "320", "-o", clean.to_str().unwrap()]);
    let exr = dir.join("frame.exr");
    let checkpoint = dir.join("frame.exr.checkpoint");
    let args = ["--spp", "320", "--checkpoint-interval", "0", "--resume", "-o", exr.to_str().unwrap()];
    let mut kills_at = Vec::new();
    for wait_for in [1u32, 64, 128] {
        let mut child = Command::new(env!("CARGO_BIN_EXE_tessera"))
            .args(["render", "--res", "32x32", "--aov", "albedo,diffuse_direct"])
            .args(args)
            .arg(root().join("fixtures/cornell_box.usda"))
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Bounded: the whole render takes a few seconds.
        let deadline = Instant::now() + Duration::from_secs(120);
        while checkpoint_end(&checkpoint).is_none_or(|end| end < wait_for) && Instant::now() < deadline {
            assert!(child.try_wait().unwrap().is_none(), "the render finished before sample {wait_for} was checkpointed");
            std::thread::sleep(Duration::from_millis(5));
        }
        child.kill().unwrap();
        child.wait().unwrap();
        kills_at.push(checkpoint_end(&checkpoint).expect("a checkpoint"));
        assert!(!exr.exists(), "a killed render left {}", exr.display());
    }
    assert!(kills_at.windows(2).all(|w| w[0] < w[1]), "each resumption went further: {kills_at:?}");
    let run = render(&["--spp", "320", "--resume", "-o", exr.to_str().unwrap()]);
    let said = String::from_utf8_lossy(&run.stderr);
    assert!(said.contains(&format!("from sample {} of 320", kills_at[2])), "{said}");
    let (a, b) = (pixels(&clean), pixels(&exr));
    for ((name, x), (_, y)) in a.iter().zip(&b) {
        assert!(x == y, "layer {name} differs after resuming at samples {kills_at:?}");
    }
    assert!(!checkpoint.exists(), "a finished frame keeps no checkpoint");
    std::fs::remove_dir_all(&dir).ok();
}
