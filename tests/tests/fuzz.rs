//! A short, deterministic fuzzing run on stable Rust, the one CI does: mutants of every
//! fixture's USD text and of its sync stream go through the same entry points as the
//! cargo-fuzz targets in `fuzz/` (README: "Fuzzing" for the longer run). Every input must end
//! in Ok or an error, never a panic; a panicking input is saved under `target/fuzz-failures/`.

use std::cell::Cell;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::sync::Once;

use tessera_tests::*;

/// The mutations' numbers: the renderer's own PCG32.
struct Rng(render_core::sampling::Pcg32);

impl Rng {
    fn below(&mut self, n: usize) -> usize {
        (self.0.next_u32() as usize) % n.max(1)
    }
    fn byte(&mut self) -> u8 {
        self.0.next_u32() as u8
    }
}

/// Values that break naive numeric code, spliced in as text or as raw bytes.
const TOKENS: &[&str] =
    &["nan", "-nan", "inf", "-inf", "1e38", "-1e38", "0", "-1", "4294967295", "99999999999999999999", "1e-45", "()", "[]", "\"", "{"];

/// One mutant of `seed`: a few byte-level edits (flip, overwrite, delete, duplicate, splice a
/// token over a number-looking byte).
fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        if v.is_empty() {
            v.push(b'0');
        }
        let i = rng.below(v.len());
        match rng.below(6) {
            0 => v[i] ^= 1 << rng.below(8),
            1 => v[i] = rng.byte(),
            2 => {
                let n = rng.below(16).min(v.len() - i);
                v.drain(i..i + n);
            }
            3 => {
                let n = rng.below(32).min(v.len() - i);
                let copy: Vec<u8> = v[i..i + n].to_vec();
                v.splice(i..i, copy);
            }
            4 => v.truncate(i),
            _ => {
                // Replace the number (or byte) at i with a hostile token.
                let end = (i..v.len())
                    .find(|&k| !(v[k].is_ascii_digit() || v[k] == b'.' || v[k] == b'-' || v[k] == b'e'))
                    .unwrap_or(v.len())
                    .max(i + 1)
                    .min(v.len());
                let t = TOKENS[rng.below(TOKENS.len())].as_bytes();
                v.splice(i..end, t.iter().copied());
            }
        }
    }
    v
}

thread_local! {
    /// Set by the panic hook on the thread that panicked. The loaders catch the USD and VDB
    /// readers' panics and turn them into errors, so a caught panic would otherwise pass as an
    /// input the reader rejected.
    static PANICKED: Cell<bool> = const { Cell::new(false) };
    /// This thread runs a fuzzing loop: its panics are expected, and not printed. Per thread,
    /// so another test failing meanwhile still prints why.
    static QUIET: Cell<bool> = const { Cell::new(false) };
}

/// The panic hook for this test binary, installed once (tests run in parallel, so hooks swapped
/// per test would restore each other's): it notes the panic for its thread, and prints it unless
/// that thread runs a fuzzing loop.
fn note_panics() {
    static INSTALL: Once = Once::new();
    INSTALL.call_once(|| {
        let print = std::panic::take_hook();
        std::panic::set_hook(Box::new(move |info| {
            PANICKED.with(|p| p.set(true));
            if !QUIET.with(Cell::get) {
                print(info);
            }
        }));
    });
}

/// Runs `f` and says whether anything panicked on this thread meanwhile, caught or not.
fn panics_in(f: impl FnOnce()) -> bool {
    PANICKED.with(|p| p.set(false));
    let escaped = catch_unwind(AssertUnwindSafe(f)).is_err();
    escaped || PANICKED.with(Cell::get)
}

/// Silences this thread's panics while `f` runs (see [`note_panics`]).
fn quietly<T>(f: impl FnOnce() -> T) -> T {
    note_panics();
    QUIET.with(|q| q.set(true));
    let out = f();
    QUIET.with(|q| q.set(false));
    out
}

fn save_failure(kind: &str, k: usize, data: &[u8]) -> String {
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/fuzz-failures");
    std::fs::create_dir_all(&dir).ok();
    let path = dir.join(format!("{kind}-{k}.bin"));
    std::fs::write(&path, data).ok();
    path.display().to_string()
}

/// Runs `f` on `n` mutants of each seed (times `TESSERA_FUZZ_SCALE`, default 1, for a longer
/// local run); returns the saved paths of inputs that panicked, whether or not the code under
/// test caught the panic.
fn run(kind: &str, seeds: &[Vec<u8>], n: usize, f: impl Fn(&[u8])) -> Vec<String> {
    let n = n * std::env::var("TESSERA_FUZZ_SCALE").ok().and_then(|s| s.parse().ok()).unwrap_or(1usize);
    let mut rng = Rng(render_core::sampling::Pcg32::new(0x7e55_e7a0, kind.len() as u64));
    let mut failures = Vec::new();
    quietly(|| {
        for (s, seed) in seeds.iter().enumerate() {
            for k in 0..n {
                let input = if k == 0 { seed.clone() } else { mutate(seed, &mut rng) };
                // A stack overflow aborts the process: the input in flight is kept for it.
                save_failure(&format!("{kind}-in-flight"), 0, &input);
                if panics_in(|| f(&input)) {
                    failures.push(save_failure(kind, s * n + k, &input));
                }
            }
        }
    });
    failures
}

/// The `.usda` fixtures, the mutation seeds of both targets.
fn usda_seeds() -> Vec<(String, Vec<u8>)> {
    all_fixtures()
        .into_iter()
        .filter(|p| p.extension().is_some_and(|e| e == "usda"))
        .filter(|p| std::fs::metadata(p).is_ok_and(|m| m.len() < 200_000))
        .map(|p| (p.display().to_string(), std::fs::read(&p).unwrap()))
        .collect()
}

#[test]
fn mutated_usd_files_never_panic_the_client() {
    let seeds: Vec<Vec<u8>> = usda_seeds().into_iter().map(|(_, d)| d).collect();
    assert!(seeds.len() > 20, "{} seeds", seeds.len());
    let failures = run("usd", &seeds, 60, |d| {
        let _ = tessera::fuzzing::usd_text(d);
    });
    assert!(failures.is_empty(), "inputs that panicked the USD translation: {failures:?}");
}

#[test]
fn mutated_sync_streams_never_panic_the_server() {
    let seeds: Vec<Vec<u8>> = usda_seeds()
        .into_iter()
        .filter_map(|(name, _)| tessera::usd::load(std::path::Path::new(&name)).ok())
        .map(|t| tessera_server::fuzzing::encode_stream(&tessera::sync::full_sync(&t)))
        .collect();
    // Every unmutated stream commits.
    for s in &seeds {
        tessera_server::fuzzing::sync_bytes(s).expect("a fixture's own sync stream commits");
    }
    let failures = run("sync", &seeds, 200, |d| {
        let _ = tessera_server::fuzzing::sync_bytes(d);
    });
    assert!(failures.is_empty(), "inputs that panicked the server's validation: {failures:?}");
}

/// A corrupt binary USD file is an error naming the file, never an abort or a panic, caught or
/// not. Two kinds of damage:
/// - windows of 8 bytes across `cornell_box.usdc` (its header, values and table of contents)
///   and the same scene packaged as `.usdz`, overwritten in turn with sizes too large,
///   negative, or all ones. openusd 0.6 as released aborted the process on the first huge size
///   (an allocation of 4 TB, 2026-12-03), which in the Python package took the DCC hosting it
///   down; third_party/openusd checks each size first;
/// - a few random bytes or hostile 32-bit integers in `cornell_box.usdc`. Before
///   third_party/openusd checked its indices, about one such file in six panicked the reader
///   (token, path and string indices out of range, 2026-12-05); the loader caught it, but the
///   CLI printed the panic and its backtrace.
#[test]
fn corrupt_binary_usd_files_are_errors_never_panics() {
    let dir = std::env::temp_dir().join(format!("tessera-corrupt-usdc-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let (mut errors, mut panicked) = (Vec::new(), Vec::new());
    quietly(|| {
        for (name, bytes, what) in windowed_damage().chain(random_damage()) {
            let file = dir.join(format!("corrupt-{name}"));
            std::fs::write(&file, bytes).unwrap();
            let mut result = None;
            if panics_in(|| result = Some(tessera::usd::load(&file))) {
                panicked.push(format!("{name}: {what}"));
            } else if let Some(Err(e)) = result {
                errors.push(format!("{e:#}"));
            }
        }
    });
    std::fs::remove_dir_all(&dir).ok();
    assert!(panicked.is_empty(), "{} corrupt files panicked the reader: {:?}", panicked.len(), &panicked[..5.min(panicked.len())]);
    assert!(
        errors.len() > 1000 && errors.iter().all(|e| e.contains("corrupt-cornell_box")),
        "{} errors, which name the file: {:?}",
        errors.len(),
        &errors[..3.min(errors.len())]
    );
}

/// Copies of the Cornell box's `.usdc` and `.usdz` with 8 bytes overwritten by a huge, negative
/// or all-ones size: (file name, bytes, what was done). Every 5th offset of the 3,197-byte
/// .usdc and every 11th of the 3,363-byte .usdz, four patterns: 3,780 files. A release run over
/// every offset of both, and over the 3,000 bytes of sections that end hard/many_lights.usdc,
/// survived too (2026-12-03).
fn windowed_damage() -> impl Iterator<Item = (&'static str, Vec<u8>, String)> {
    let patterns = [[0xff; 8], 0x7fff_ffff_ffff_fff0u64.to_le_bytes(), (-(1i64 << 40)).to_le_bytes(), 0x7fff_ffffu64.to_le_bytes()];
    [("cornell_box.usdc", 5), ("cornell_box.usdz", 11)].into_iter().flat_map(move |(name, step)| {
        let clean = std::fs::read(fixture(name)).unwrap();
        (0..clean.len() - 8).step_by(step).flat_map(move |offset| {
            let clean = clean.clone();
            patterns.into_iter().map(move |pattern| {
                let mut bytes = clean.clone();
                bytes[offset..offset + 8].copy_from_slice(&pattern);
                (name, bytes, format!("{pattern:02x?} at {offset}"))
            })
        })
    })
}

/// 800 copies of the Cornell box's `.usdc` with one to six random bytes, or hostile 32-bit
/// integers, past its 88-byte bootstrap (which the windows cover); seeded, so a failure
/// reproduces. A release run of 2,300 such files made from nine fixtures with skinning, node
/// graphs, instancers, curves, subsets and time samples (written as .usdc by usd-core) found
/// no other panic (2026-12-05).
fn random_damage() -> impl Iterator<Item = (&'static str, Vec<u8>, String)> {
    let name = "cornell_box.usdc";
    let clean = std::fs::read(fixture(name)).unwrap();
    let mut rng = Rng(render_core::sampling::Pcg32::new(0xc0de_f11e, 3));
    let hostile = [u32::MAX, 0x7fff_ffff, 0, 0x8000_0001];
    (0..800).map(move |k| {
        let mut bytes = clean.clone();
        for _ in 0..1 + rng.below(6) {
            let at = 88 + rng.below(bytes.len() - 92);
            match k % 2 {
                0 => bytes[at] = rng.byte(),
                _ => bytes[at..at + 4].copy_from_slice(&hostile[rng.below(4)].to_le_bytes()),
            }
        }
        (name, bytes, format!("random damage {k}"))
    })
}

/// Replays one saved input with its panic and backtrace visible:
/// `TESSERA_FUZZ_INPUT=target/fuzz-failures/usd-3.bin cargo test -p tessera-tests --test e2e replay -- --ignored --nocapture`
/// (a name starting with `sync` replays it as a sync stream, anything else as USD text).
#[test]
#[ignore = "replays the input named by TESSERA_FUZZ_INPUT"]
fn replay() {
    let path = std::env::var("TESSERA_FUZZ_INPUT").expect("set TESSERA_FUZZ_INPUT");
    let data = std::fs::read(&path).unwrap();
    let sync = std::path::Path::new(&path).file_name().is_some_and(|n| n.to_string_lossy().starts_with("sync"));
    let result = if sync { tessera_server::fuzzing::sync_bytes(&data).map(|_| ()) } else { tessera::fuzzing::usd_text(&data) };
    println!("{result:?}");
}

/// The fixtures' texture files (under 200 KB), mutated, through the server's decoding.
#[test]
fn mutated_texture_files_never_panic_the_decoder() {
    fn walk(dir: &std::path::Path, out: &mut Vec<Vec<u8>>) {
        for entry in std::fs::read_dir(dir).unwrap().flatten() {
            let p = entry.path();
            if p.is_dir() {
                walk(&p, out);
            } else if p.extension().is_some_and(|e| ["png", "jpg", "jpeg", "exr", "hdr", "tga", "tif"].contains(&&*e.to_string_lossy()))
                && std::fs::metadata(&p).is_ok_and(|m| m.len() < 200_000)
            {
                out.push(std::fs::read(&p).unwrap());
            }
        }
    }
    let mut seeds = Vec::new();
    walk(&fixture(""), &mut seeds);
    seeds.push(hostile_inputs::png_claiming(16384, 16384));
    assert!(seeds.len() >= 5, "{} texture seeds", seeds.len());
    let failures = run("texture", &seeds, 40, |d| {
        let _ = tessera_server::fuzzing::texture_bytes(d);
    });
    assert!(failures.is_empty(), "inputs that panicked texture decoding: {failures:?}");
}

/// Render settings, from the defaults and from every knob at an extreme, mutated as bytes.
#[test]
fn mutated_render_settings_never_panic_the_server() {
    use prost::Message;
    use tessera_proto::v1 as pb;
    let extremes = [
        pb::RenderSettings::default(),
        pb::RenderSettings { width: 16384, height: 16384, spp: u32::MAX, max_depth: u32::MAX, tile_size: 1, ..Default::default() },
        pb::RenderSettings {
            threads: u32::MAX,
            noise_threshold: f32::NAN,
            clamp_indirect: -1.0,
            pixel_aspect: f32::INFINITY,
            ..Default::default()
        },
        pb::RenderSettings {
            aovs: vec!["albedo".into(), "nonsense".into()],
            caustics: 99,
            sampler: -1,
            light_split_budget: 1 << 30,
            coarse_start: u32::MAX,
            ..Default::default()
        },
        pb::RenderSettings { coarse_start: 64, width: 1, height: 1, ..Default::default() },
    ];
    let seeds: Vec<Vec<u8>> = extremes.iter().map(|s| s.encode_to_vec()).collect();
    let failures = run("settings", &seeds, 300, |d| {
        let _ = tessera_server::fuzzing::render_settings_bytes(d);
    });
    assert!(failures.is_empty(), "inputs that panicked render-settings validation: {failures:?}");
}
