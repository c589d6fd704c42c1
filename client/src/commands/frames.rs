//! Frame ranges for farm schedulers: `--frames 1-240x2` with an output pattern that names
//! each frame (`shot.####.exr` or `shot.$F4.exr`, as husk and Houdini spell it),
//! `ALF_PROGRESS` lines (Tractor's and husk's convention), and `--skip-existing`.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicI64, Ordering};

use anyhow::{Context, Result, bail};

/// Most frames one `--frames` may name (a typo such as `1-1000000000` fails fast).
const MAX_FRAMES: usize = 1_000_000;

/// Frames from `A`, `A-B` or `A-BxS`, comma-separated (`1-10,15,20-40x5`), in order given.
pub fn parse_frames(spec: &str) -> Result<Vec<i64>> {
    let mut frames = Vec::new();
    for part in spec.split(',').map(str::trim) {
        let bad = || format!("--frames: '{part}' is not FRAME, FIRST-LAST or FIRST-LASTxSTEP");
        let (range, step) = match part.split_once('x') {
            Some((r, s)) => (r, s.parse::<i64>().ok().filter(|s| *s > 0).with_context(bad)?),
            None => (part, 1),
        };
        // A leading '-' is a negative frame, not a range.
        let (first, last) = match range[1.min(range.len())..].find('-').map(|i| i + 1) {
            Some(i) => (range[..i].parse::<i64>().ok().with_context(bad)?, range[i + 1..].parse::<i64>().ok().with_context(bad)?),
            None => {
                let f = range.parse::<i64>().ok().with_context(bad)?;
                (f, f)
            }
        };
        if last < first {
            bail!("--frames: '{part}' ends before it starts");
        }
        if ((last - first) / step) as usize + frames.len() >= MAX_FRAMES {
            bail!("--frames: '{spec}' names more than {MAX_FRAMES} frames");
        }
        frames.extend((first..=last).step_by(step as usize));
    }
    Ok(frames)
}

/// The output path of `frame`: the last run of `#` in the file name becomes the frame
/// zero-padded to that many digits, or `$F4` / `$F` becomes it padded to 4 / not padded.
/// `None` when the pattern names no frame.
pub fn frame_path(pattern: &Path, frame: i64) -> Option<PathBuf> {
    let name = pattern.file_name()?.to_string_lossy().to_string();
    let named = if let Some(end) = name.rfind('#') {
        let start = name[..end].trim_end_matches('#').len();
        let width = end + 1 - start;
        format!("{}{:0width$}{}", &name[..start], frame, &name[end + 1..])
    } else if let Some(i) = name.find("$F") {
        let digits = name[i + 2..].chars().take_while(char::is_ascii_digit).count();
        let width: usize = name[i + 2..i + 2 + digits].parse().unwrap_or(0);
        format!("{}{:0width$}{}", &name[..i], frame, &name[i + 2 + digits..])
    } else {
        return None;
    };
    Some(pattern.with_file_name(named))
}

/// Every frame's output path; an error when several frames would share one file.
pub fn frame_paths(pattern: &Path, frames: &[i64]) -> Result<Vec<PathBuf>> {
    match frames {
        [one] => Ok(vec![frame_path(pattern, *one).unwrap_or_else(|| pattern.to_path_buf())]),
        _ => frames
            .iter()
            .map(|&f| {
                frame_path(pattern, f).with_context(|| {
                    format!("-o {}: several frames need the frame in the file name (shot.####.exr or shot.$F4.exr)", pattern.display())
                })
            })
            .collect(),
    }
}

/// The last `ALF_PROGRESS` percentage printed by this process (-1: none yet).
static ALF_LAST: AtomicI64 = AtomicI64::new(-1);

/// Prints `ALF_PROGRESS n%` for the whole job (frame `index` of `count`, `frame_percent` of it
/// done) when the integer percentage moves: once per value over the whole process, so the
/// end of one frame and the start of the next do not say the same number twice.
pub fn alf_progress(index: usize, count: usize, frame_percent: f32) {
    let overall = ((index as f32 + frame_percent.clamp(0.0, 100.0) / 100.0) / count.max(1) as f32 * 100.0).floor() as i64;
    if ALF_LAST.swap(overall, Ordering::Relaxed) != overall {
        println!("ALF_PROGRESS {overall}%");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_specs_as_schedulers_write_them() {
        assert_eq!(parse_frames("1-5").unwrap(), [1, 2, 3, 4, 5]);
        assert_eq!(parse_frames("1-240x60").unwrap(), [1, 61, 121, 181]);
        assert_eq!(parse_frames("7").unwrap(), [7]);
        assert_eq!(parse_frames("1-3,10,20-30x5").unwrap(), [1, 2, 3, 10, 20, 25, 30]);
        assert_eq!(parse_frames("-2-1").unwrap(), [-2, -1, 0, 1]);
        for bad in ["", "a-b", "5-1", "1-10x0", "1-10x-2", "1-2000000000"] {
            assert!(parse_frames(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn output_patterns_name_each_frame() {
        let p = |s: &str, f| frame_path(Path::new(s), f).map(|p| p.display().to_string());
        assert_eq!(p("out/shot.####.exr", 7).as_deref(), Some("out/shot.0007.exr"));
        assert_eq!(p("out/shot.#.exr", 12).as_deref(), Some("out/shot.12.exr"));
        assert_eq!(p("out/shot.$F4.exr", 7).as_deref(), Some("out/shot.0007.exr"));
        assert_eq!(p("out/shot.$F.exr", 7).as_deref(), Some("out/shot.7.exr"));
        assert_eq!(p("out/shot.exr", 7), None);
        assert_eq!(frame_paths(Path::new("out/shot.exr"), &[3]).unwrap(), [PathBuf::from("out/shot.exr")]);
        assert!(frame_paths(Path::new("out/shot.exr"), &[1, 2]).is_err(), "two frames, one file");
    }
}
