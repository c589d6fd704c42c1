//! `tessera render`: USD in, multi-layer EXR and PNG preview out, through a render server
//! (an embedded one when no `--server` is given).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use indicatif::{ProgressBar, ProgressStyle};
use render_core::integrator::IntegratorSettings;
use tessera_proto::v1 as pb;

use crate::film::ExactFilm;
use crate::output;
use crate::remote::{Connection, RenderOptions, RenderReport};

/// Inputs of one `tessera render`.
#[derive(Clone, Debug)]
pub struct RenderJob {
    /// Scene file.
    pub scene: PathBuf,
    /// Output EXR; empty for the `productName` of the stage's RenderProduct.
    pub output: PathBuf,
    /// Render options.
    pub options: RenderOptions,
    /// Server URL; `None` starts an embedded server.
    pub server: Option<String>,
    /// Show a progress bar.
    pub progress: bool,
    /// Time code for animated attributes; `None` for the stage's default.
    pub frame: Option<f64>,
    /// Refinement level of subdivision surfaces that name none (0: their cages).
    pub subdivision_level: u32,
    /// Shutter interval (open, close) in frames relative to the frame, overriding the camera's.
    pub shutter: Option<(f64, f64)>,
    /// Transform samples over the shutter for prims that move.
    pub motion_samples: usize,
    /// Samples per cubic span of BasisCurves' tubes.
    pub curve_samples: usize,
    /// Light a scene that has no lights with a white dome (see
    /// [`crate::usd::Translation::add_default_light`]).
    pub default_light: bool,
    /// Fail, before rendering, when reading the scene gave warnings (skipped prims,
    /// unresolved inputs): for pipelines that would rather stop than render a partial scene.
    pub strict: bool,
    /// Print `ALF_PROGRESS` lines as frame `.0` of `.1` of a frame range.
    pub alf_progress: Option<(usize, usize)>,
    /// Whether the render keeps its exact film (to checkpoint it, or to write a slice).
    pub film: FilmMode,
}

/// How a render keeps its samples.
#[derive(Clone, Debug, Default)]
pub enum FilmMode {
    /// The server resolves its tiles; nothing survives the process.
    #[default]
    Pixels,
    /// The client keeps the exact film and writes it beside the output every `interval`
    /// (at the first pass end after it); `resume` continues from such a file.
    Checkpointed {
        /// Time between checkpoints.
        interval: std::time::Duration,
        /// Continue from the checkpoint when there is one from the same settings.
        resume: bool,
    },
    /// Render samples `range` of every pixel and write their film (not an image) to
    /// `partial`, for `tessera merge`.
    Slice {
        /// The samples.
        range: std::ops::Range<u32>,
        /// Where the film goes.
        partial: PathBuf,
    },
}

/// Where a checkpointed render keeps its film: beside the output, named after it.
pub fn checkpoint_path(output: &Path) -> PathBuf {
    let mut name = output.file_name().unwrap_or_default().to_os_string();
    name.push(".checkpoint");
    output.with_file_name(name)
}

impl RenderJob {
    /// A render of `scene` into `output` with `options` on an embedded server, every other
    /// setting at the CLI's default: the stage's default time, the default subdivision level,
    /// motion and curve samples, a default light for unlit scenes, warnings not fatal, no
    /// progress output, no film kept.
    pub fn new(scene: PathBuf, output: PathBuf, options: RenderOptions) -> Self {
        RenderJob {
            scene,
            output,
            options,
            server: None,
            progress: false,
            frame: None,
            subdivision_level: crate::usd::DEFAULT_SUBDIVISION_LEVEL,
            shutter: None,
            motion_samples: crate::usd::DEFAULT_MOTION_SAMPLES,
            curve_samples: crate::usd::curves::DEFAULT_CURVE_SAMPLES,
            default_light: true,
            strict: false,
            alf_progress: None,
            film: FilmMode::default(),
        }
    }

    /// How the scene is read for this job.
    pub fn load_options(&self) -> crate::usd::LoadOptions {
        crate::usd::LoadOptions {
            frame: self.frame,
            subdivision_level: self.subdivision_level,
            shutter: self.shutter,
            motion_samples: self.motion_samples,
            curve_samples: self.curve_samples,
        }
    }

    /// What the frame's output depends on: the settings asked for, the scene file's bytes
    /// and the frame. Recorded in the EXR header; `--skip-existing` re-renders a frame whose
    /// file records another.
    /// The sample count is left out (the EXR records it as `sppAsked`), so the slices of one
    /// render, its checkpoints and the render itself share the hash.
    pub fn settings_hash(&self) -> Result<String> {
        let scene = std::fs::read(&self.scene).with_context(|| format!("cannot read {}", self.scene.display()))?;
        let options = RenderOptions { spp: 0, first_sample: 0, stream_film: false, ..self.options.clone() };
        let asked = format!(
            "{:?}|{:?}|{}|{}|{:?}|{}|{}|{}",
            options,
            self.frame,
            self.default_light,
            self.subdivision_level,
            self.shutter,
            self.motion_samples,
            self.curve_samples,
            tessera_wire::content_hash(&scene)
        );
        Ok(tessera_wire::content_hash(asked.as_bytes()))
    }

    /// True when the output exists, complete, from these settings (atomic writes mean an
    /// existing file is a whole one).
    pub fn already_rendered(&self) -> bool {
        let recorded = crate::output::exr_attribute(&self.output, "settingsHash");
        let spp = crate::output::exr_attribute(&self.output, "sppAsked");
        recorded.is_some() && recorded == self.settings_hash().ok() && spp == Some(self.options.spp.to_string())
    }
}

/// Reads the scene, renders it and writes the outputs. Returns the report for callers
/// (tests) that want the numbers.
pub async fn run(job: &RenderJob) -> Result<RenderReport> {
    let mut session = FrameSession::open(job).await?;
    let report = session.render(job).await;
    session.close().await?;
    report
}

/// One server session for a run of frames: the first frame's scene is synced whole, each
/// later frame sends only what changed since the one before (`sync::changes`), as a DCC
/// does between edits.
pub struct FrameSession {
    embedded: Option<tessera_server::EmbeddedServer>,
    conn: Connection,
    held: Option<crate::usd::Translation>,
}

impl FrameSession {
    /// Starts an embedded server unless the job names one, and opens a session on it.
    pub async fn open(job: &RenderJob) -> Result<Self> {
        let embedded = match &job.server {
            Some(_) => None,
            None => Some(tessera_server::EmbeddedServer::start().await?),
        };
        let url = job.server.clone().unwrap_or_else(|| embedded.as_ref().expect("started above").url());
        let conn = Connection::connect(&url, "tessera-cli").await?;
        Ok(FrameSession { embedded, conn, held: None })
    }

    /// Closes the session and stops the embedded server.
    pub async fn close(mut self) -> Result<()> {
        self.conn.close().await.ok();
        if let Some(server) = self.embedded.take() {
            server.stop().await?;
        }
        Ok(())
    }

    /// Reads the job's scene at its frame, brings the session up to date with it, renders and
    /// writes the outputs.
    pub async fn render(&mut self, job: &RenderJob) -> Result<RenderReport> {
        let t0 = Instant::now();
        let translation = load_translation(job).await?;
        let synced = match &self.held {
            None => Some(self.conn.sync_scene(&translation).await),
            Some(before) => {
                let items = crate::sync::changes(before, &translation);
                // A frame where nothing moves sends nothing (a Sync must carry at least one item).
                if items.is_empty() { None } else { Some(self.conn.sync(items).await) }
            }
        };
        let mut said = Vec::new();
        if let Some(sync) = synced {
            let sync = sync.with_context(|| format!("{}: the server rejected the scene", job.scene.display()))?;
            for w in &sync.warnings {
                eprintln!("warning: {w}");
            }
            said = sync.warnings;
        }
        self.held = Some(translation);
        let translation = self.held.as_ref().expect("just set");
        render_synced(job, &mut self.conn, translation, t0.elapsed().as_secs_f64(), &said).await
    }
}

/// Renders the scene the session holds and writes the outputs; prints the plan, warnings
/// (but those the scene's sync already printed, `said`: the render repeats the commit's),
/// progress and one summary line.
async fn render_synced(
    job: &RenderJob,
    conn: &mut Connection,
    translation: &crate::usd::Translation,
    load_secs: f64,
    said: &[String],
) -> Result<RenderReport> {
    let options = &with_denoise_guides(resolve_options(&job.options, translation));
    // Before rendering: a missing library should not cost the render. The same device then
    // denoises the result.
    let denoiser = options.denoise.then(|| crate::denoise::Denoiser::new(options.threads as usize)).transpose()?;
    let output_path = output_of(&job.output, translation)?;

    let bar = if job.progress { ProgressBar::new(options.spp as u64) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{elapsed_precise}] {bar:32} {pos}/{len} spp  {msg}  ETA {eta}").expect("valid template"),
    );
    // Above the bar on a terminal; a hidden bar (stderr piped, as on a farm) prints nothing,
    // so the plan and the warnings go to stderr directly.
    let say = |line: String| if bar.is_hidden() { eprintln!("{line}") } else { bar.println(line) };
    let mut tiles_this_pass = 0u32;
    let asked = std::time::Instant::now();
    let mut first_tile = None;
    let mut on_event = |e: &pb::render_event::Event| match e {
        pb::render_event::Event::Started(s) => {
            if !s.plan.is_empty() {
                say("render plan:".to_string());
                for p in &s.plan {
                    say(format!("  + {:<16} {}", p.effect, p.reason));
                }
                for line in translation.reader_plan().lines() {
                    say(line.to_string());
                }
            }
            for w in s.warnings.iter().filter(|w| !said.contains(w)) {
                say(format!("warning: {w}"));
            }
        }
        pb::render_event::Event::Tile(pb::Tile { pass_index, .. }) | pb::render_event::Event::Film(pb::FilmTile { pass_index, .. })
            if !matches!(e, pb::render_event::Event::Tile(t) if t.aov != "beauty") =>
        {
            first_tile.get_or_insert_with(|| asked.elapsed());
            tiles_this_pass += 1;
            bar.set_message(format!("pass {pass_index} tiles {tiles_this_pass}"));
        }
        pb::render_event::Event::Progress(p) => {
            if let Some((index, count)) = job.alf_progress {
                super::frames::alf_progress(index, count, p.percent);
            }
            tiles_this_pass = 0;
            bar.set_position(p.spp as u64);
            bar.set_message(format!("{:.1} Mrays/s  noise {:.2}%", p.rays_per_second / 1e6, 100.0 * p.estimated_noise));
        }
        pb::render_event::Event::Restarted(r) => say(format!("scene changed (version {}): restarting", r.scene_version)),
        _ => {}
    };
    let report = match &job.film {
        FilmMode::Pixels => conn.render(options, &mut on_event).await?,
        mode => {
            let (report, film) = render_film(job, conn, options, &output_path, &mut on_event).await?;
            bar.finish_and_clear();
            if let FilmMode::Slice { partial, range } = mode {
                return write_slice(film, partial, range, exr_metadata(job, options, translation, &report), report);
            }
            report
        }
    };
    bar.finish_and_clear();
    let mut report = report;
    if let Some(denoiser) = &denoiser {
        denoise_report(&mut report, denoiser)?;
    }
    write_outputs(&output_path, &report, &exr_metadata(job, options, translation, &report))?;
    if let FilmMode::Checkpointed { .. } = job.film {
        // The frame is whole at its final path: its checkpoint has nothing left to give.
        std::fs::remove_file(checkpoint_path(&output_path)).ok();
    }
    eprint!("{}", convergence_table(&report.progress));
    if let Some(t) = options.noise_threshold {
        eprintln!("{}", adaptive_summary(&report, t));
    }
    let f = &report.finished;
    println!(
        "{}: {}x{} {} spp in {:.2} s (first tile {:.0} ms, +{:.2} s load) | {:.2} Mrays/s, {:.2} Mpaths/s | noise {:.2}% -> {} (+ {})",
        job.scene.file_name().map_or_else(|| job.scene.display().to_string(), |n| n.to_string_lossy().to_string()),
        options.width,
        options.height,
        f.spp,
        f.seconds,
        first_tile.map_or(f64::NAN, |d| d.as_secs_f64() * 1e3),
        load_secs,
        f.rays_per_second / 1e6,
        f.paths_per_second / 1e6,
        100.0 * f.estimated_noise,
        output_path.display(),
        output::preview_path(&output_path).display()
    );
    Ok(report)
}

/// Renders with an exact film: a slice's samples, or the whole render checkpointed every
/// interval and resumed from the last checkpoint when asked. Returns the report (its image
/// resolved from the film when it starts at sample 0) and the film.
async fn render_film(
    job: &RenderJob,
    conn: &mut Connection,
    options: &RenderOptions,
    output: &Path,
    on_event: &mut (dyn FnMut(&pb::render_event::Event) + Send),
) -> Result<(RenderReport, ExactFilm)> {
    if options.noise_threshold.is_some() {
        anyhow::bail!(
            "--checkpoint-interval and --sample-range render without adaptive sampling (--noise-threshold): a later slice could not judge convergence without the samples before it"
        );
    }
    let hash = job.settings_hash()?;
    let mut opts = RenderOptions { stream_film: true, ..options.clone() };
    let (w, h) = (options.width, options.height);
    let (mut film, checkpoint) = match &job.film {
        FilmMode::Slice { range, .. } => {
            (opts.first_sample, opts.spp) = (range.start, range.end);
            (ExactFilm::new(w, h, range.start), None)
        }
        FilmMode::Checkpointed { interval, resume } => {
            let path = checkpoint_path(output);
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
            }
            let resumed = resume.then(|| resumable(&path, &hash, options)).flatten();
            if let Some(f) = &resumed {
                eprintln!("resuming {} from sample {} of {}", output.display(), f.range.end, options.spp);
            }
            (resumed.unwrap_or_else(|| ExactFilm::new(w, h, 0)), Some((path, *interval)))
        }
        FilmMode::Pixels => unreachable!("pixel renders keep no film"),
    };
    opts.first_sample = opts.first_sample.max(film.range.end);
    film.metadata = vec![("settingsHash".to_string(), hash)];
    let mut last = Instant::now();
    let on_pass = |f: &ExactFilm| {
        match &checkpoint {
            Some((path, interval)) if f.range.end < opts.spp && last.elapsed() >= *interval => {
                atomically(path, |tmp| f.save(tmp))?;
                last = Instant::now();
            }
            _ => {}
        }
        Ok(())
    };
    let mut report = conn.render_into(&opts, Some(&mut film), on_event, on_pass).await?;
    // A resumed render's server saw only the samples after the checkpoint; the film has all.
    if let Some((noise, mean_spp)) = film.noise_and_mean_spp() {
        (report.finished.estimated_noise, report.finished.mean_spp) = (noise as f32, mean_spp);
    }
    if let Some(aovs) = (!report.started.aovs.is_empty()).then(|| report.started.aovs.join(",")) {
        film.metadata.push(("aovs".to_string(), aovs));
    }
    Ok((report, film))
}

/// The checkpoint at `path` when it holds an earlier part of this render (same settings and
/// scene, ending at one of its passes); else `None`, said when a file was there.
fn resumable(path: &Path, hash: &str, options: &RenderOptions) -> Option<ExactFilm> {
    if !path.exists() {
        return None;
    }
    let film = match ExactFilm::load(path) {
        Ok(f) => f,
        Err(e) => {
            eprintln!("warning: {e:#}; rendering from the start");
            return None;
        }
    };
    let fits = film.metadata_value("settingsHash") == Some(hash)
        && (film.width, film.height) == (options.width, options.height)
        && film.range.start == 0
        && film.range.end < options.spp
        && render_core::render::is_pass_boundary(film.range.end, options.spp);
    if !fits {
        eprintln!("warning: {} is from other settings or another scene; rendering from the start", path.display());
    }
    fits.then_some(film)
}

/// Writes a slice's film to `partial` (atomically) with the header the merged EXR will carry.
fn write_slice(
    mut film: ExactFilm,
    partial: &Path,
    range: &std::ops::Range<u32>,
    metadata: Vec<(String, String)>,
    report: RenderReport,
) -> Result<RenderReport> {
    let aovs = film.metadata_value("aovs").map(str::to_string);
    film.metadata = metadata;
    film.metadata.extend(aovs.map(|a| ("aovs".to_string(), a)));
    if let Some(dir) = partial.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    atomically(partial, |tmp| film.save(tmp))?;
    println!("samples {}..{} in {:.2} s -> {}", range.start, range.end, report.finished.seconds, partial.display());
    Ok(report)
}

/// `tessera merge`: one EXR from the films of a render's slices, which must together cover
/// samples 0 to their end; bit-identical to rendering those samples in one process.
pub fn merge(parts: &[PathBuf], output: &Path, denoise: bool) -> Result<ExactFilm> {
    let films = parts.iter().map(|p| ExactFilm::load(p)).collect::<Result<Vec<_>>>()?;
    let seconds: f64 = films.iter().filter_map(|f| f.metadata_value("seconds")?.parse::<f64>().ok()).sum();
    let merged = ExactFilm::merge(films)?;
    let aovs: Vec<String> = merged.metadata_value("aovs").unwrap_or("beauty").split(',').map(str::to_string).collect();
    let image = merged.resolve(&aovs)?;
    let end = merged.range.end.to_string();
    let (noise, mean_spp) = merged.noise_and_mean_spp().unwrap_or_default();
    let mut metadata: Vec<(String, String)> = merged
        .metadata
        .iter()
        .filter(|(k, _)| k != "aovs")
        .map(|(k, v)| match k.as_str() {
            "spp" | "sppAsked" => (k.clone(), end.clone()),
            "seconds" => (k.clone(), format!("{seconds:.3}")),
            "estimated_noise" => (k.clone(), format!("{noise:.5}")),
            "mean_spp" => (k.clone(), format!("{mean_spp:.2}")),
            _ => (k.clone(), v.clone()),
        })
        .collect();
    let mut report = RenderReport { image, ..Default::default() };
    if denoise {
        denoise_report(&mut report, &crate::denoise::Denoiser::new(0)?)?;
        metadata.extend(denoise_metadata(&report.image));
    }
    write_outputs(output, &report, &metadata)?;
    Ok(merged)
}

/// The stage translated at the job's frame, with a default camera and light where it has
/// none (each said once), and its warnings and unrendered prims reported.
async fn load_translation(job: &RenderJob) -> Result<crate::usd::Translation> {
    let scene = job.scene.clone();
    let options = job.load_options();
    let mut translation = tokio::task::spawn_blocking(move || crate::usd::load_with(&scene, options)).await??;
    if translation.add_default_camera() {
        eprintln!("note: the Z-up stage has no camera; it is framed from the front (-Y), 25 degrees above the ground, Z up");
    }
    if job.default_light && translation.add_default_light() {
        eprintln!("note: the scene has no lights; it renders under a white dome of radiance 1 (--no-default-light renders it black)");
    }
    for w in &translation.warnings {
        eprintln!("warning: {w}");
    }
    if !translation.skipped.is_empty() {
        eprintln!("warning: {} prim(s) not rendered: {}", translation.skipped.len(), translation.skipped.join(", "));
    }
    if job.strict && !translation.warnings.is_empty() {
        anyhow::bail!(
            "{}: {} warning(s) reading the scene, and --strict makes them errors",
            job.scene.display(),
            translation.warnings.len()
        );
    }
    Ok(translation)
}

/// The options with the albedo and normal AOVs added when denoising asks for them (OIDN's
/// guides; they are written too).
fn with_denoise_guides(mut o: RenderOptions) -> RenderOptions {
    if o.denoise {
        for guide in ["albedo", "normal"] {
            if !o.aovs.iter().any(|a| a == guide) {
                o.aovs.push(guide.to_string());
            }
        }
    }
    o
}

/// Adds the denoised layers to a finished render's image and says what it did.
pub fn denoise_report(report: &mut RenderReport, denoiser: &crate::denoise::Denoiser) -> Result<()> {
    let t = Instant::now();
    let added = crate::denoise::denoise_image(&mut report.image, denoiser)?;
    eprintln!("denoised {} with Open Image Denoise in {:.0} ms", added.join(", "), t.elapsed().as_secs_f64() * 1e3);
    Ok(())
}

/// What the header says of denoising: the filter, its guides, the layers it wrote.
pub fn denoise_metadata(image: &crate::output::Image) -> Option<(String, String)> {
    let layers: Vec<&str> = image.layers.keys().filter(|k| k.ends_with("_denoised")).map(String::as_str).collect();
    (!layers.is_empty()).then(|| {
        (
            "denoised".to_string(),
            format!("Open Image Denoise RT, hdr, guides albedo + normal (prefiltered, cleanAux); layers {}", layers.join(", ")),
        )
    })
}

/// The EXR header's `tessera/*` attributes: scene, samples, time, noise, settings, units,
/// the primId table and the plan.
fn exr_metadata(
    job: &RenderJob,
    options: &RenderOptions,
    translation: &crate::usd::Translation,
    report: &RenderReport,
) -> Vec<(String, String)> {
    let f = &report.finished;
    vec![
        ("scene".to_string(), job.scene.display().to_string()),
        ("settingsHash".to_string(), job.settings_hash().unwrap_or_default()),
        ("spp".to_string(), f.spp.to_string()),
        ("sppAsked".to_string(), options.spp.to_string()),
        ("seconds".to_string(), format!("{:.3}", f.seconds)),
        ("estimated_noise".to_string(), format!("{:.5}", f.estimated_noise)),
        (
            "settings".to_string(),
            format!(
                "{}x{} spp={} max_depth={} seed={} sampler={} energy_compensation={} clamp={} noise_threshold={} caustics={} texture_filtering={} light_split_budget={}",
                options.width,
                options.height,
                options.spp,
                options.max_depth,
                options.seed,
                if options.sobol { "sobol" } else { "independent" },
                if options.energy_compensation { "on" } else { "off" },
                options.clamp_indirect.map_or("off".to_string(), |c| c.to_string()),
                options.noise_threshold.map_or("off".to_string(), |c| c.to_string()),
                if options.avoid_caustics { "avoid" } else { "full" },
                if options.texture_filtering { "on" } else { "off" },
                match (options.light_splitting, options.light_split_budget) {
                    (false, _) => 1,
                    (true, 0) => 8,
                    (true, b) => b,
                },
            ),
        ),
        ("mean_spp".to_string(), format!("{:.2}", f.mean_spp)),
        // Positions and depths are in scene units: what one is worth, and which way is up.
        ("metersPerUnit".to_string(), translation.meters_per_unit.to_string()),
        ("upAxis".to_string(), if translation.z_up { "Z" } else { "Y" }.to_string()),
        // The primId AOV's table: line k names id k + 1.
        ("primIdPaths".to_string(), report.started.prim_paths.join("\n")),
        (
            "plan".to_string(),
            report
                .started
                .plan
                .iter()
                .map(|p| p.effect.as_str())
                .chain((!translation.subdivided.is_empty()).then_some("subdivision"))
                .chain((!translation.skinned.is_empty()).then_some("skinning"))
                .chain((!translation.curves.is_empty()).then_some("curves"))
                .chain(options.denoise.then_some("denoise"))
                .collect::<Vec<_>>()
                .join(","),
        ),
    ]
    .into_iter()
    .chain(denoise_metadata(&report.image))
    .collect()
}

/// Options the command line left open, from the stage's RenderSettings and its first
/// RenderProduct (whose own camera and resolution win over the settings', as UsdRender says):
/// the camera (when no `--camera`), the resolution (width 0 means no `--res`; else 512x512),
/// the pixel aspect (0 means no `--pixel-aspect`) and the AOVs of the product's RenderVars
/// (when no `--aov`).
pub fn resolve_options(given: &RenderOptions, translation: &crate::usd::Translation) -> RenderOptions {
    let mut o = given.clone();
    if let Some(rs) = &translation.render_settings {
        let product = rs.products.first();
        if o.camera.is_empty()
            && let Some(c) = product.and_then(|p| p.camera.as_ref()).or(rs.camera.as_ref())
        {
            o.camera = c.clone();
        }
        if o.width == 0
            && let Some((w, h)) = product.and_then(|p| p.resolution).or(rs.resolution)
        {
            (o.width, o.height) = (w, h);
        }
        if o.pixel_aspect == 0.0 {
            o.pixel_aspect = rs.pixel_aspect.unwrap_or(0.0);
        }
        if o.aovs.is_empty() {
            o.aovs = product.map(|p| p.aovs.clone()).unwrap_or_default();
        }
    }
    if o.width == 0 || o.height == 0 {
        (o.width, o.height) = (512, 512);
    }
    o
}

/// The EXR to write: `given` (`-o`), else the `productName` of the stage's first
/// RenderProduct; neither is an error saying so.
pub fn output_of(given: &Path, translation: &crate::usd::Translation) -> Result<PathBuf> {
    if !given.as_os_str().is_empty() {
        return Ok(given.to_path_buf());
    }
    let product = translation.render_settings.as_ref().and_then(|rs| rs.products.first());
    match product.and_then(|p| p.name.as_ref()) {
        Some(name) => Ok(PathBuf::from(name)),
        None => anyhow::bail!("no output file: give -o/--output, or a RenderSettings with a RenderProduct that has a productName"),
    }
}

/// The render plan of a scene: what the renderer will simulate and which prims call for it,
/// from the same commit the server performs (`render_core::scene::commit`), plus what the
/// USD translation could not render.
pub fn explain_plan(scene: &Path, options: crate::usd::LoadOptions) -> Result<String> {
    explain_plan_for(scene, options, &IntegratorSettings::default())
}

/// [`explain_plan`] for a render with `settings`, which also decide which path loop runs.
pub fn explain_plan_for(scene: &Path, options: crate::usd::LoadOptions, settings: &IntegratorSettings) -> Result<String> {
    let translation = crate::usd::load_with(scene, options)?;
    let committed = render_core::scene::commit(&translation.to_scene_desc(), &mut render_core::scene::BlasCache::default())
        .with_context(|| format!("{}: the scene does not commit", scene.display()))?;
    // What the reader did goes with what the renderer does, before what it leaves out.
    let plan = committed.plan.to_string();
    let split = plan.find("  - ").unwrap_or(plan.len());
    let reader = translation.reader_plan();
    let path_loop = path_loop_line(committed.plan.features, settings);
    let mut out = format!("render plan for {}:\n{}{reader}{path_loop}{}", scene.display(), &plan[..split], &plan[split..]);
    for w in translation.warnings.iter().chain(&committed.warnings) {
        out += &format!("  ! {w}\n");
    }
    Ok(out)
}

/// Which path loop the render runs, and what calls for the general one: a scene and settings
/// without any of its machinery run the loop compiled without it.
fn path_loop_line(features: render_core::plan::Features, settings: &IntegratorSettings) -> String {
    let causes: Vec<&str> = render_core::integrator::general_loop_causes(features, settings).collect();
    match causes.is_empty() {
        true => {
            let left_out: Vec<&str> = render_core::integrator::FULL_LOOP_FEATURES.iter().map(|f| f.name()).collect();
            format!("  = {:<18} specialised: compiled without the machinery of {}\n", "path loop", left_out.join(", "))
        }
        false => format!("  = {:<18} general, for {}\n", "path loop", causes.join(", ")),
    }
}

/// The render's price, pass by pass: samples, elapsed time, estimated noise (relative
/// standard error of the image's mean luminance) and the pixels still sampling.
pub fn convergence_table(progress: &[pb::Progress]) -> String {
    let mut out = String::from("convergence:\n  pass    spp   elapsed s   noise %   active px\n");
    for p in progress {
        // One sample per pixel cannot estimate a variance.
        let noise = if p.spp < 2 { "-".to_string() } else { format!("{:.3}", 100.0 * p.estimated_noise) };
        out += &format!("  {:>4} {:>6} {:>11.3} {:>9} {:>11}\n", p.pass_index, p.spp, p.elapsed_seconds, noise, p.active_pixels);
    }
    out
}

/// What adaptive sampling did: samples per pixel on average against the budget, the share of
/// pixels that reached the target, and the spread of samples over the image (from the
/// `sampleCount` AOV when it was rendered).
pub fn adaptive_summary(report: &RenderReport, threshold: f32) -> String {
    let f = &report.finished;
    let pixels = (report.image.width as u64 * report.image.height as u64).max(1);
    let converged = report.progress.last().map_or(0, |p| pixels.saturating_sub(p.active_pixels));
    let mut out = format!(
        "adaptive sampling (target {:.2}%): {:.1} spp on average of {} ({:.0}% of the samples), {:.1}% of pixels reached the target",
        100.0 * threshold,
        f.mean_spp,
        f.spp,
        100.0 * f.mean_spp / f.spp.max(1) as f64,
        100.0 * converged as f64 / pixels as f64
    );
    if let Some((_, counts)) = report.image.layers.get("sampleCount") {
        let (lo, hi) = counts.iter().fold((f32::MAX, 0.0f32), |(lo, hi), &c| (lo.min(c), hi.max(c)));
        out += &format!("; per pixel {lo:.0} to {hi:.0}");
    }
    out + &region_map(&f.regions, report.image.width, report.image.height)
}

/// Most cells across and down in the printed map of samples per region.
const MAP_CELLS: (u32, u32) = (8, 6);

/// The samples per pixel of the render's regions (tiles) on a coarse grid of the image, at most
/// [`MAP_CELLS`]; a cell averages the tiles whose centres fall in it, weighted by their pixels.
/// Empty without regions.
pub fn region_map(regions: &[pb::RegionSamples], width: u32, height: u32) -> String {
    let tile = regions.iter().fold((0, 0), |(w, h), r| (r.width.max(w), r.height.max(h)));
    if regions.is_empty() || tile.0 == 0 || tile.1 == 0 {
        return String::new();
    }
    let cols = width.div_ceil(tile.0).clamp(1, MAP_CELLS.0);
    let rows = height.div_ceil(tile.1).clamp(1, MAP_CELLS.1);
    // (samples, pixels) per cell.
    let mut cells = vec![(0.0f64, 0.0f64); (cols * rows) as usize];
    for r in regions {
        let area = r.width as f64 * r.height as f64;
        let cx = ((r.x as f64 + 0.5 * r.width as f64) / width.max(1) as f64 * cols as f64) as u32;
        let cy = ((r.y as f64 + 0.5 * r.height as f64) / height.max(1) as f64 * rows as f64) as u32;
        let cell = &mut cells[(cy.min(rows - 1) * cols + cx.min(cols - 1)) as usize];
        cell.0 += r.mean_spp * area;
        cell.1 += area;
    }
    let mut out = format!("\nsamples per pixel by region ({cols}x{rows}, top row first):");
    for row in cells.chunks(cols as usize) {
        out.push_str("\n ");
        for &(samples, pixels) in row {
            out += &if pixels > 0.0 { format!(" {:>6.0}", samples / pixels) } else { format!(" {:>6}", "-") };
        }
    }
    out
}

/// Writes the EXR and its PNG preview.
pub fn write_outputs(exr: &Path, report: &RenderReport, metadata: &[(String, String)]) -> Result<()> {
    if let Some(dir) = exr.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).with_context(|| format!("cannot create {}", dir.display()))?;
    }
    atomically(exr, |tmp| output::write_exr(tmp, &report.image, metadata))?;
    atomically(&output::preview_path(exr), |tmp| output::write_png(tmp, &report.image))
}

/// Writes `path` through a temporary file beside it, renamed into place once complete: a
/// process killed mid-write leaves no truncated or black frame at the final path (what
/// farms call "black frames"), only a `.partial` file that the next write replaces.
pub fn atomically(path: &Path, write: impl FnOnce(&Path) -> Result<()>) -> Result<()> {
    let name = path.file_name().with_context(|| format!("{}: not a file name", path.display()))?.to_string_lossy();
    // The extension stays last: the image writers pick the format by it.
    let tmp = path.with_file_name(format!(
        ".{name}.partial-{}.{}",
        std::process::id(),
        path.extension().map_or("".into(), |e| e.to_string_lossy())
    ));
    if let Err(e) = write(&tmp) {
        std::fs::remove_file(&tmp).ok();
        return Err(e);
    }
    std::fs::rename(&tmp, path).with_context(|| format!("cannot move the finished {} into place", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The final path appears only complete: a failed write leaves neither it nor the
    /// temporary file, and a successful one leaves just the final file.
    #[test]
    fn outputs_appear_whole_or_not_at_all() {
        let dir = std::env::temp_dir().join(format!("tessera-atomic-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let frame = dir.join("shot.0001.exr");
        let e = atomically(&frame, |tmp| {
            std::fs::write(tmp, b"half a frame")?;
            anyhow::bail!("killed mid-write")
        });
        assert!(e.is_err());
        assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 0, "nothing left behind");
        atomically(&frame, |tmp| {
            assert_eq!(tmp.extension().unwrap(), "exr", "writers choose the format by the extension");
            Ok(std::fs::write(tmp, b"a whole frame")?)
        })
        .unwrap();
        let names: Vec<String> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into()).collect();
        assert_eq!(names, ["shot.0001.exr"]);
        assert_eq!(std::fs::read(&frame).unwrap(), b"a whole frame");
        std::fs::remove_dir_all(&dir).ok();
    }

    fn region(x: u32, y: u32, size: u32, mean_spp: f64) -> pb::RegionSamples {
        pb::RegionSamples { x, y, width: size, height: size, mean_spp }
    }

    /// One tile per cell prints each tile's own count, in rows from the top.
    #[test]
    fn a_small_image_maps_each_tile() {
        let regions = [region(0, 0, 16, 16.0), region(16, 0, 16, 32.0), region(0, 16, 16, 64.0), region(16, 16, 16, 256.0)];
        let map = region_map(&regions, 32, 32);
        let rows: Vec<Vec<f64>> = map.lines().skip(2).map(|l| l.split_whitespace().map(|v| v.parse().unwrap()).collect()).collect();
        assert!(map.contains("(2x2, top row first)"), "{map}");
        assert_eq!(rows, vec![vec![16.0, 32.0], vec![64.0, 256.0]], "{map}");
    }

    /// More tiles than cells: a cell is the pixel-weighted mean of its tiles (a narrow edge
    /// tile counts for its few pixels).
    #[test]
    fn many_tiles_merge_into_cells_by_their_pixels() {
        // 20 x 1 tiles of 8 px across a 156-px-wide image: the last one is 4 px wide.
        let regions: Vec<pb::RegionSamples> = (0..20)
            .map(|i| pb::RegionSamples { x: 8 * i, y: 0, width: if i == 19 { 4 } else { 8 }, height: 8, mean_spp: (i + 1) as f64 })
            .collect();
        let map = region_map(&regions, 156, 8);
        let cells: Vec<f64> = map.lines().nth(2).unwrap().split_whitespace().map(|v| v.parse().unwrap()).collect();
        assert_eq!(cells.len(), 8, "{map}");
        // Cells are 19.5 px wide and tile centres 8 px apart from 4 px: cell 0 holds tiles 0
        // and 1, (1 + 2) / 2 = 1.5, printed as 2; the last cell tiles 17 to 19, the narrow
        // one at half weight: (18·8 + 19·8 + 20·4) / 20 = 18.8, printed as 19.
        assert_eq!((cells[0], cells[7]), (2.0, 19.0), "{map}");
        assert!(cells.windows(2).all(|w| w[0] <= w[1]), "{map}");
        assert!(region_map(&[], 10, 10).is_empty());
    }
}
