//! `tessera`: the command-line client.

use std::io::Write;
use std::path::PathBuf;

use anyhow::{Context, Result, bail};
use clap::{Parser, Subcommand};
use tessera::commands::render::{FilmMode, RenderJob, run};
use tessera::quality::Quality;
use tessera::remote::RenderOptions;

#[derive(Parser)]
#[command(version, about = "Tessera: render USD scenes on a Tessera render server")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

/// How finely the reader samples what moves and what curves: flags `render` and `inspect` share.
#[derive(clap::Args, Clone, Copy, Debug)]
struct SceneSampling {
    /// Shutter interval OPEN,CLOSE in frames relative to the frame (`-0.25,0.25`),
    /// overriding the camera's shutter:open/close; equal ends render without motion blur.
    #[arg(long, value_parser = parse_shutter, allow_hyphen_values = true)]
    shutter: Option<(f64, f64)>,
    /// Transform samples over the shutter for prims and cameras that move (more follow
    /// a rotation's arc more closely; docs/accuracy-vs-time.md).
    #[arg(long, default_value_t = tessera::usd::DEFAULT_MOTION_SAMPLES as u64, value_parser = clap::value_parser!(u64).range(2..=64))]
    motion_samples: u64,
    /// Samples along each cubic span of BasisCurves' tubes (docs/accuracy-vs-time.md).
    #[arg(long, default_value_t = tessera::usd::curves::DEFAULT_CURVE_SAMPLES as u64, value_parser = clap::value_parser!(u64).range(1..=64))]
    curve_samples: u64,
}

impl SceneSampling {
    /// The reader's options with these and the frame and subdivision level given.
    fn load_options(self, frame: Option<f64>, subdivision_level: u32) -> tessera::usd::LoadOptions {
        let (motion_samples, curve_samples) = (self.motion_samples as usize, self.curve_samples as usize);
        tessera::usd::LoadOptions { frame, subdivision_level, shutter: self.shutter, motion_samples, curve_samples }
    }
}

#[derive(Subcommand)]
// Parsed once per process: the size of its largest variant costs nothing.
#[allow(clippy::large_enum_variant)]
enum Command {
    /// Render a USD file (.usda, .usdc, .usdz) to a multi-layer EXR and a PNG preview.
    Render {
        /// The scene.
        scene: PathBuf,
        /// Output EXR path; a PNG preview is written beside it (default: the `productName` of
        /// the stage's RenderSettings' first RenderProduct).
        #[arg(short, long)]
        output: Option<PathBuf>,
        /// Quality preset: sets --spp, --max-depth and --clamp unless given (see
        /// docs/accuracy-vs-time.md for what each costs and reaches).
        #[arg(long, value_enum, default_value_t = Quality::Preview)]
        quality: Quality,
        /// Samples per pixel (default: the preset's).
        #[arg(long)]
        spp: Option<u32>,
        /// Resolution as WIDTHxHEIGHT (default: the stage's RenderSettings, else 512x512).
        #[arg(long)]
        res: Option<String>,
        /// Pixel width over height (default: the stage's RenderSettings pixelAspectRatio,
        /// else 1).
        #[arg(long)]
        pixel_aspect: Option<f32>,
        /// Edge of the render tiles in pixels, 8-512 (default 64): the units progressive
        /// updates stream in and the regions the final per-region sample counts describe.
        #[arg(long)]
        tile_size: Option<u32>,
        /// Camera prim path (default: the stage RenderSettings camera, else the first camera).
        #[arg(long, default_value = "")]
        camera: String,
        /// Maximum scattering events per path, 1 = direct lighting only (default: the
        /// preset's).
        #[arg(long)]
        max_depth: Option<u32>,
        /// Sampling seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Extra AOVs, comma-separated: albedo, normal, depth, position, and the light-path
        /// components diffuse, specular, transmission, subsurface, emission (which sum to the
        /// beauty), each but emission also split as <name>_direct and <name>_indirect.
        #[arg(long, value_delimiter = ',')]
        aov: Vec<String>,
        /// Render server URL (e.g. http://127.0.0.1:50051). Without it an embedded server
        /// starts in-process.
        #[arg(long)]
        server: Option<String>,
        /// Render threads on the server (0 = all cores).
        #[arg(long, default_value_t = 0)]
        threads: u32,
        /// Print the render plan (what is simulated, and which prims call for it) and exit
        /// without rendering.
        #[arg(long)]
        explain_plan: bool,
        /// Kulla-Conty energy compensation (multiple scattering in rough microfacets, glass,
        /// and the diffuse-specular coupling).
        #[arg(long, value_enum, default_value_t = OnOff::On)]
        energy_compensation: OnOff,
        /// Mip-map texture lookups by each ray's footprint (off: only pixel supersampling
        /// filters textures; docs/accuracy-vs-time.md measures both).
        #[arg(long, value_enum, default_value_t = OnOff::On)]
        texture_filtering: OnOff,
        /// Adaptive splitting in the light tree: up to 8 lights per shading point where one
        /// cannot represent a cluster (off: one light per point, cheaper and noisier).
        #[arg(long, value_enum, default_value_t = OnOff::On)]
        light_splitting: OnOff,
        /// With light splitting on, the most lights one shading point samples (1-8, default 8;
        /// docs/accuracy-vs-time.md measures each budget at equal time).
        #[arg(long)]
        light_split_budget: Option<u32>,
        /// Time code at which to evaluate animated attributes (default: the stage's
        /// startTimeCode, else 0).
        #[arg(long, conflicts_with = "frames", allow_negative_numbers = true)]
        frame: Option<f64>,
        /// Refinement level of subdivision surfaces (meshes whose subdivisionScheme is not
        /// none) that do not name their own: 2^level segments per cage edge; 0 renders cages.
        #[arg(long, default_value_t = tessera::usd::DEFAULT_SUBDIVISION_LEVEL, value_parser = clap::value_parser!(u32).range(0..=8))]
        subdivision_level: u32,
        #[command(flatten)]
        sampling: SceneSampling,
        /// Render a frame range in one process: FIRST-LAST[xSTEP], comma-separated
        /// (`1-240x2`, `-10-10`); `-o` names each frame with `####` or `$F4` (`out/shot.####.exr`).
        #[arg(long, allow_hyphen_values = true)]
        frames: Option<String>,
        /// Print `ALF_PROGRESS n%` lines over the whole job (Tractor's and husk's convention).
        #[arg(long)]
        alf_progress: bool,
        /// Skip frames whose output exists and was rendered with the same settings and scene
        /// (recorded in its EXR header); others are rendered again.
        #[arg(long)]
        skip_existing: bool,
        /// The numbers paths draw: Owen-scrambled Sobol points or independent random numbers.
        #[arg(long, value_enum, default_value_t = SamplerArg::Sobol)]
        sampler: SamplerArg,
        /// Caustic paths: `full` path tracing (unbiased), or `avoid` them as Imageworks do
        /// (roughness clamping and transparent shadows through smooth glass: biased, far less
        /// noisy; see docs/accuracy-vs-time.md for what it costs in error).
        #[arg(long, value_enum, default_value_t = CausticsArg::Full)]
        caustics: CausticsArg,
        /// Run every effect whether or not the scene calls for it: the same image, slower
        /// (what `tessera bench effects` measures the render plan against).
        #[arg(long)]
        force_all_effects: bool,
        /// Render a scene without lights black, instead of under the default white dome.
        #[arg(long)]
        no_default_light: bool,
        /// Fail when reading the scene gives warnings (a malformed prim is otherwise skipped
        /// with a warning and the rest renders, exit status 0).
        #[arg(long)]
        strict: bool,
        /// Firefly clamp: limit each indirect contribution's largest component to this value
        /// (off by default; it darkens what it clamps, and the render reports it).
        #[arg(long)]
        clamp: Option<f32>,
        /// Adaptive sampling: a pixel stops receiving samples once the relative standard error
        /// of its mean (worst over its 3x3 neighbours) is below this, e.g. 0.01 for 1%; off by
        /// default. Pixels take at least 16 samples first.
        #[arg(long)]
        noise_threshold: Option<f32>,
        /// Render only samples FIRST-END of every pixel (a slice of a frame split across
        /// machines) and write their film to --partial; `tessera merge` combines slices into
        /// the EXR the whole render writes, bit for bit. FIRST and END must start passes: 0,
        /// a power of two up to 64, or a multiple of 64 (END may also be --spp).
        #[arg(long, requires = "partial", conflicts_with_all = ["frames", "checkpoint_interval"])]
        sample_range: Option<String>,
        /// Where --sample-range writes its film.
        #[arg(long, requires = "sample_range")]
        partial: Option<PathBuf>,
        /// Write the render's film beside the output (`OUTPUT.checkpoint`) at the first pass
        /// end after every SECONDS, atomically; --resume continues from it.
        #[arg(long)]
        checkpoint_interval: Option<f64>,
        /// Continue from the output's checkpoint when one from the same settings and scene is
        /// there (bit-identical to an uninterrupted render); otherwise start afresh.
        #[arg(long)]
        resume: bool,
        /// Denoise the final image with Intel Open Image Denoise (`pip install pyoidn`):
        /// adds `beauty_denoised` (and `<aov>_denoised` for light-path AOVs), guided by the
        /// albedo and normal AOVs, which are rendered and written too. The raw beauty stays.
        #[arg(long)]
        denoise: bool,
    },
    /// Render on a farm through a Redis Streams queue: submit jobs, run workers, watch them.
    Farm {
        #[command(subcommand)]
        what: FarmCommand,
    },
    /// Combine the films of a frame's sample slices (`render --sample-range --partial`)
    /// into its EXR: the same pixels as rendering all the samples at once.
    Merge {
        /// The slices' films, in any order; together they must cover samples 0 to their end.
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        /// The EXR to write (a PNG preview goes beside it).
        #[arg(short, long)]
        output: PathBuf,
        /// Denoise the merged image (slices are merged first and denoised once); the slices
        /// must have rendered the albedo and normal AOVs.
        #[arg(long)]
        denoise: bool,
    },
    /// Measure what the quality knobs buy and cost, and write the report.
    Bench {
        #[command(subcommand)]
        what: BenchCommand,
    },
    /// Print what the client reads from a USD file: meshes with their world transforms and
    /// materials, instancers, lights, cameras, material networks, skipped prims.
    Inspect {
        /// The scene.
        scene: PathBuf,
        /// Print JSON (the only format so far; the same shape `fixtures/inspect_usd.py`
        /// prints from Pixar's usd-core).
        #[arg(long)]
        json: bool,
        /// Time code for animated attributes.
        #[arg(long, allow_negative_numbers = true)]
        frame: Option<f64>,
        /// As `render --subdivision-level`.
        #[arg(long, default_value_t = tessera::usd::DEFAULT_SUBDIVISION_LEVEL, value_parser = clap::value_parser!(u32).range(0..=8))]
        subdivision_level: u32,
        #[command(flatten)]
        sampling: SceneSampling,
    },
}

#[derive(Subcommand)]
enum BenchCommand {
    /// Error against a reference versus render time for every quality knob; writes
    /// docs/accuracy-vs-time.md and its SVG plot.
    Accuracy {
        /// The report to write (the plot goes beside it, as .svg).
        #[arg(long, default_value = "docs/accuracy-vs-time.md")]
        out: PathBuf,
        /// The fixtures directory.
        #[arg(long, default_value = "fixtures")]
        fixtures: PathBuf,
        /// Image edge of the Cornell box renders.
        #[arg(long, default_value_t = 64)]
        size: u32,
        /// Samples per pixel of the reference renders.
        #[arg(long, default_value_t = 8192)]
        reference_spp: u32,
    },
    /// 10 000 lights against one light of the same total power at equal time, per split
    /// budget; prints the table (docs/accuracy-vs-time.md carries it too).
    Lights {
        /// The fixtures directory.
        #[arg(long, default_value = "fixtures")]
        fixtures: PathBuf,
        /// Image edge.
        #[arg(long, default_value_t = 32)]
        size: u32,
        /// Samples per pixel of the references.
        #[arg(long, default_value_t = 2048)]
        reference_spp: u32,
        /// Also write the table here.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// What the render plan saves: each fixture rendered as planned and with every effect
    /// forced on; prints the speed-up and the difference between the images (equal within
    /// noise). Writes docs/render-plan.md.
    Effects {
        /// The report to write.
        #[arg(long, default_value = "docs/render-plan.md")]
        out: PathBuf,
        /// The fixtures directory.
        #[arg(long, default_value = "fixtures")]
        fixtures: PathBuf,
        /// Image edge.
        #[arg(long, default_value_t = 96)]
        size: u32,
        /// Samples per pixel.
        #[arg(long, default_value_t = 32)]
        spp: u32,
    },
}

#[derive(Subcommand)]
enum FarmCommand {
    /// Put a job on the queue: one task per frame, or per (frame, sample slice) with
    /// --split-samples. Prints the job id. The scene and the outputs must be on storage
    /// every worker reads and writes.
    Submit {
        /// The scene.
        scene: PathBuf,
        /// Frames: FIRST-LAST[xSTEP], comma-separated.
        #[arg(long, allow_hyphen_values = true)]
        frames: String,
        /// Output pattern with `####` or `$F4` for the frame number.
        #[arg(short, long)]
        output: PathBuf,
        /// The queue: redis://HOST:PORT.
        #[arg(long)]
        redis: String,
        /// Samples per pixel.
        #[arg(long, default_value_t = 64)]
        spp: u32,
        /// Split each frame's samples into this many slices, rendered by any workers and
        /// merged exactly when all are done.
        #[arg(long, default_value_t = 1)]
        split_samples: u32,
        /// 0 (lowest) to 9: workers take tasks of the highest priority first.
        #[arg(long, default_value_t = tessera::farm::DEFAULT_PRIORITY)]
        priority: u8,
        /// Further `tessera render` arguments, after `--` (`-- --res 1920x1080 --aov albedo`).
        #[arg(last = true)]
        render_args: Vec<String>,
    },
    /// Render tasks from the queue until stopped.
    Worker {
        /// The queue: redis://HOST:PORT.
        #[arg(long)]
        redis: String,
        /// This worker's name on the queue (default: host name and process id).
        #[arg(long)]
        name: Option<String>,
        /// Render server URL (default: an embedded server per task).
        #[arg(long)]
        server: Option<String>,
        /// Seconds a task's worker may stay silent before another claims it.
        #[arg(long, default_value_t = 60.0)]
        claim_after: f64,
        /// Seconds between a frame's checkpoints.
        #[arg(long, default_value_t = 30.0)]
        checkpoint_interval: f64,
        /// Exit after this many seconds without a task (default: never).
        #[arg(long)]
        exit_when_idle: Option<f64>,
    },
    /// Per-task state (queued, rendering where and how far, done, failed and why) and the
    /// job's progress.
    Status {
        /// The job id `submit` printed.
        job: String,
        /// The queue: redis://HOST:PORT.
        #[arg(long)]
        redis: String,
    },
    /// Stop a job: queued tasks are dropped, running ones stopped at the next heartbeat.
    Cancel {
        /// The job id.
        job: String,
        /// The queue: redis://HOST:PORT.
        #[arg(long)]
        redis: String,
    },
    /// Put a job's failed tasks back on the queue.
    Retry {
        /// The job id.
        job: String,
        /// The queue: redis://HOST:PORT.
        #[arg(long)]
        redis: String,
        /// Retry the failed tasks (the only kind there is to retry).
        #[arg(long)]
        failed: bool,
    },
}

/// `tessera merge`.
fn merge(parts: &[PathBuf], output: &std::path::Path, denoise: bool) -> Result<()> {
    let merged = tessera::commands::render::merge(parts, output, denoise)?;
    println!("{} slices, samples 0..{} -> {}", parts.len(), merged.range.end, output.display());
    Ok(())
}

/// `tessera farm ...`.
async fn farm(what: FarmCommand) -> Result<()> {
    use tessera::farm::{Redis, queue, worker};
    let secs = |s: f64, what: &str| match s.is_finite() && s >= 0.0 {
        true => Ok(std::time::Duration::from_secs_f64(s)),
        false => Err(anyhow::anyhow!("{what} must be a number of seconds, got {s}")),
    };
    match what {
        FarmCommand::Submit { scene, frames, output, redis, spp, split_samples, priority, render_args } => {
            let frames = tessera::commands::frames::parse_frames(&frames)?;
            let submission = queue::Submission { scene, frames, output, spp, split: split_samples, render_args, priority };
            println!("{}", queue::submit(&mut Redis::connect(&redis).await?, &submission).await?);
        }
        FarmCommand::Worker { redis, name, server, claim_after, checkpoint_interval, exit_when_idle } => {
            let claim_after = secs(claim_after, "--claim-after")?;
            let cfg = worker::WorkerConfig {
                name: name.unwrap_or_else(|| format!("{}-{}", hostname(), std::process::id())),
                redis,
                server,
                claim_after,
                // Three heartbeats per claim period: one late beat does not lose the task.
                heartbeat: (claim_after / 3).max(std::time::Duration::from_millis(50)),
                checkpoint_interval: secs(checkpoint_interval, "--checkpoint-interval")?,
                exit_when_idle: exit_when_idle.map(|s| secs(s, "--exit-when-idle")).transpose()?,
                render_exe: std::env::current_exe()?,
            };
            let summary = worker::run(&cfg).await?;
            eprintln!("worker {}: {} tasks done, {} failed", cfg.name, summary.done, summary.failed);
        }
        FarmCommand::Status { job, redis } => print!("{}", queue::status(&mut Redis::connect(&redis).await?, &job).await?),
        FarmCommand::Cancel { job, redis } => {
            queue::cancel(&mut Redis::connect(&redis).await?, &job).await?;
            println!("job {job} cancelled");
        }
        FarmCommand::Retry { job, redis, failed: _ } => {
            let n = queue::retry_failed(&mut Redis::connect(&redis).await?, &job).await?;
            println!("{n} failed tasks of job {job} queued again");
        }
    }
    Ok(())
}

fn hostname() -> String {
    std::fs::read_to_string("/etc/hostname").map(|h| h.trim().to_string()).unwrap_or_else(|_| "worker".into())
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum SamplerArg {
    Sobol,
    Independent,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum CausticsArg {
    Full,
    Avoid,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
enum OnOff {
    On,
    Off,
}

/// `FIRST-END` of `--sample-range`.
fn parse_sample_range(s: &str) -> Result<std::ops::Range<u32>> {
    let parsed = s.split_once('-').and_then(|(a, b)| Some(a.trim().parse::<u32>().ok()?..b.trim().parse::<u32>().ok()?));
    match parsed {
        Some(r) if r.start < r.end => Ok(r),
        _ => bail!("--sample-range must look like 64-128 (first sample, end sample, first below end), got '{s}'"),
    }
}

/// What the film options ask for: a slice, a checkpointed render, or neither.
fn film_mode(sample_range: Option<String>, partial: Option<PathBuf>, checkpoint_interval: Option<f64>, resume: bool) -> Result<FilmMode> {
    Ok(match (sample_range, partial, checkpoint_interval) {
        (Some(range), Some(partial), _) => FilmMode::Slice { range: parse_sample_range(&range)?, partial },
        (_, _, Some(secs)) if secs.is_finite() && secs >= 0.0 => {
            FilmMode::Checkpointed { interval: std::time::Duration::from_secs_f64(secs), resume }
        }
        (_, _, Some(secs)) => bail!("--checkpoint-interval must be a number of seconds, got {secs}"),
        // A resume without new checkpoints still continues from an old one.
        _ if resume => FilmMode::Checkpointed { interval: std::time::Duration::MAX, resume },
        _ => FilmMode::Pixels,
    })
}

fn parse_res(s: &str) -> Result<(u32, u32)> {
    let Some((w, h)) = s.split_once(['x', 'X']) else { bail!("--res must look like 640x480, got '{s}'") };
    let (w, h): (u32, u32) = (w.trim().parse()?, h.trim().parse()?);
    if w == 0 || h == 0 {
        bail!("--res must be at least 1x1");
    }
    Ok((w, h))
}

#[tokio::main]
async fn main() {
    tracing_subscriber::fmt()
        .with_writer(std::io::stderr)
        .with_span_events(tracing_subscriber::fmt::format::FmtSpan::CLOSE)
        .with_env_filter(tracing_subscriber::EnvFilter::try_from_default_env().unwrap_or_else(|_| "off".into()))
        .init();
    if let Err(e) = real_main().await {
        eprintln!("error: {e:#}");
        std::process::exit(tessera::exit::code_of(&e));
    }
}

/// Renders each frame of a range to the path its pattern names, in one process and one
/// server session (each frame after the first sends only what changed).
async fn render_frames(job: RenderJob, frames: &[i64], alf: bool, skip_existing: bool) -> Result<()> {
    let paths = tessera::commands::frames::frame_paths(&job.output, frames)?;
    let mut session = tessera::commands::render::FrameSession::open(&job).await?;
    for (i, (&frame, output)) in frames.iter().zip(paths).enumerate() {
        let job = RenderJob { frame: Some(frame as f64), output, alf_progress: alf.then_some((i, frames.len())), ..job.clone() };
        if skip_existing && job.already_rendered() {
            eprintln!("frame {frame}: {} already rendered with these settings; skipped", job.output.display());
        } else {
            session.render(&job).await.with_context(|| format!("frame {frame}"))?;
        }
        if alf {
            tessera::commands::frames::alf_progress(i, frames.len(), 100.0);
        }
    }
    session.close().await
}

async fn real_main() -> Result<()> {
    match Cli::parse().command {
        Command::Bench { what } => bench(what)?,
        Command::Inspect { scene, json: _, frame, subdivision_level, sampling } => {
            let options = sampling.load_options(frame, subdivision_level);
            // A closed pipe (`| head`) is not an error worth a panic.
            let _ = writeln!(std::io::stdout(), "{:#}", tessera::commands::inspect::inspect(&scene, options)?);
        }
        Command::Farm { what } => farm(what).await?,
        Command::Merge { parts, output, denoise } => merge(&parts, &output, denoise)?,
        Command::Render { scene, explain_plan: true, frame, subdivision_level, sampling, aov, caustics, force_all_effects, .. } => {
            // The settings that choose the path loop, as the server derives them.
            let settings = render_core::integrator::IntegratorSettings {
                light_path_aovs: aov.iter().any(|a| render_core::film::Aov::from_name(a).is_some_and(|a| a.is_extra())),
                caustics: if caustics == CausticsArg::Avoid {
                    render_core::caustics::CausticMode::Avoid
                } else {
                    render_core::caustics::CausticMode::Full
                },
                force_all_effects,
                ..Default::default()
            };
            let options = sampling.load_options(frame, subdivision_level);
            print!("{}", tessera::commands::render::explain_plan_for(&scene, options, &settings)?);
        }
        cmd @ Command::Render { explain_plan: false, .. } => render_command(cmd).await?,
    }
    Ok(())
}

/// `tessera render`: one frame, or a range, with the options the command line gives.
async fn render_command(cmd: Command) -> Result<()> {
    let Command::Render {
        scene,
        output,
        spp,
        res,
        pixel_aspect,
        tile_size,
        camera,
        max_depth,
        seed,
        aov,
        server,
        threads,
        energy_compensation,
        texture_filtering,
        light_splitting,
        light_split_budget,
        frame,
        subdivision_level,
        sampling,
        frames,
        alf_progress,
        skip_existing,
        sampler,
        caustics,
        force_all_effects,
        no_default_light,
        strict,
        clamp,
        noise_threshold,
        quality,
        explain_plan: false,
        sample_range,
        partial,
        checkpoint_interval,
        resume,
        denoise,
    } = cmd
    else {
        unreachable!("called for render commands")
    };
    let film = film_mode(sample_range, partial, checkpoint_interval, resume)?;
    let preset = quality.preset();
    let (spp, max_depth, clamp) = (spp.unwrap_or(preset.spp), max_depth.unwrap_or(preset.max_depth), clamp.or(preset.clamp));
    // 0x0: not given; the scene's RenderSettings or 512x512 decide (RenderJob::run).
    let (width, height) = res.as_deref().map(parse_res).transpose()?.unwrap_or((0, 0));
    let energy_compensation = energy_compensation == OnOff::On;
    let options = RenderOptions {
        width,
        height,
        spp,
        max_depth,
        seed,
        camera,
        aovs: aov,
        threads,
        progressive_f16: true,
        energy_compensation,
        texture_filtering: texture_filtering == OnOff::On,
        light_splitting: light_splitting == OnOff::On,
        light_split_budget: light_split_budget.unwrap_or(0),
        sobol: sampler == SamplerArg::Sobol,
        clamp_indirect: clamp,
        noise_threshold,
        avoid_caustics: caustics == CausticsArg::Avoid,
        force_all_effects,
        pixel_aspect: pixel_aspect.unwrap_or(0.0),
        tile_size: tile_size.unwrap_or(0),
        // Final renders start with full passes (coarse passes are for viewports).
        coarse_start: 0,
        first_sample: 0,
        stream_film: false,
        denoise,
    };
    let progress = std::io::IsTerminal::is_terminal(&std::io::stderr());
    let job = RenderJob {
        scene,
        output: output_path(&film, output),
        options,
        server,
        progress,
        frame,
        subdivision_level,
        shutter: sampling.shutter,
        motion_samples: sampling.motion_samples as usize,
        curve_samples: sampling.curve_samples as usize,
        default_light: !no_default_light,
        strict,
        alf_progress: None,
        film,
    };
    match frames {
        None => render_one(job, alf_progress, skip_existing).await?,
        Some(spec) => render_frames(job, &tessera::commands::frames::parse_frames(&spec)?, alf_progress, skip_existing).await?,
    }
    Ok(())
}

/// Where a render writes: the path given, else a slice's film, else nothing yet (the scene's
/// RenderProduct names the file, RenderJob::run).
fn output_path(film: &FilmMode, output: Option<PathBuf>) -> PathBuf {
    match (film, output) {
        (_, Some(o)) => o,
        (FilmMode::Slice { partial, .. }, None) => partial.clone(),
        (_, None) => PathBuf::new(),
    }
}

/// `tessera bench ...`: the renderer's benchmarks that write the docs' reports.
fn bench(what: BenchCommand) -> Result<()> {
    match what {
        BenchCommand::Accuracy { out, fixtures, size, reference_spp } => {
            let (report, _) = tessera::bench::accuracy::accuracy(&tessera::bench::accuracy::AccuracyBench {
                fixtures,
                out: out.clone(),
                size,
                reference_spp,
            })?;
            print!("{report}");
            eprintln!("wrote {}", out.display());
        }
        BenchCommand::Effects { out, fixtures, size, spp } => {
            let names = tessera::bench::effects::FIXTURES.iter().map(|s| s.to_string()).collect();
            let bench = tessera::bench::effects::EffectsBench { fixtures, names, size, spp, out: Some(out.clone()) };
            let (report, _) = tessera::bench::effects::effects(&bench)?;
            print!("{report}");
            eprintln!("wrote {}", out.display());
        }
        BenchCommand::Lights { fixtures, size, reference_spp, out } => {
            let bench =
                tessera::bench::lights::LightsBench { out, ..tessera::bench::lights::LightsBench::new(fixtures, size, reference_spp) };
            let (report, _) = tessera::bench::lights::lights(&bench)?;
            print!("{report}");
        }
    }
    Ok(())
}

/// One frame (the job's own, or the stage's default), unless `--skip-existing` finds it done.
async fn render_one(job: RenderJob, alf: bool, skip_existing: bool) -> Result<()> {
    if skip_existing && job.already_rendered() {
        eprintln!("{}: already rendered with these settings; skipped", job.output.display());
        return Ok(());
    }
    run(&RenderJob { alf_progress: alf.then_some((0, 1)), ..job }).await?;
    if alf {
        tessera::commands::frames::alf_progress(0, 1, 100.0);
    }
    Ok(())
}

/// `--shutter OPEN,CLOSE`: two finite frame offsets, open not after close.
fn parse_shutter(s: &str) -> Result<(f64, f64), String> {
    let (a, b) = s.split_once(',').ok_or("expected OPEN,CLOSE, e.g. -0.25,0.25")?;
    let parse = |x: &str| {
        x.trim()
            .parse::<f64>()
            .map_err(|e| format!("'{x}': {e}"))
            .and_then(|v| if v.is_finite() { Ok(v) } else { Err(format!("'{x}' is not finite")) })
    };
    let (open, close) = (parse(a)?, parse(b)?);
    if open > close {
        return Err(format!("the shutter opens at {open}, after it closes at {close}"));
    }
    Ok((open, close))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shutter_flags_parse_and_refuse_what_is_no_interval() {
        assert_eq!(parse_shutter("-0.25,0.25"), Ok((-0.25, 0.25)));
        assert_eq!(parse_shutter(" 0 , 0 "), Ok((0.0, 0.0)), "equal ends: no blur");
        assert!(parse_shutter("0.5,0").unwrap_err().contains("after it closes"));
        assert!(parse_shutter("0,inf").unwrap_err().contains("not finite"));
        assert!(parse_shutter("0.5").unwrap_err().contains("OPEN,CLOSE"));
        assert!(parse_shutter("a,1").is_err());
    }

    /// USD time codes may be negative (a shot's pre-roll): `--frame -2` and `--frames -10-10`
    /// are values, not flags.
    #[test]
    fn negative_frames_parse_as_values() {
        let frame = |args: &[&str]| match Cli::try_parse_from(args).map(|c| c.command) {
            Ok(Command::Inspect { frame, .. }) | Ok(Command::Render { frame, .. }) => frame,
            other => panic!("{args:?}: {:?}", other.err()),
        };
        assert_eq!(frame(&["tessera", "inspect", "s.usda", "--frame", "-2"]), Some(-2.0));
        assert_eq!(frame(&["tessera", "render", "s.usda", "--frame", "-0.5"]), Some(-0.5));
        let Ok(Command::Render { frames, .. }) =
            Cli::try_parse_from(["tessera", "render", "s.usda", "--frames", "-10-10", "-o", "f.####.exr"]).map(|c| c.command)
        else {
            panic!("--frames -10-10 parses");
        };
        assert_eq!(frames.as_deref(), Some("-10-10"));
    }
}
