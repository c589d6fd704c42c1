//! A connection to a render server: one session, synced scene, progressive renders.

use anyhow::{Context, Result};
use tessera_proto::v1 as pb;
use tessera_proto::v1::render_client::RenderClient;
use tonic::service::interceptor::InterceptedService;
use tonic::transport::{Certificate, Channel, ClientTlsConfig};

use crate::output::Image;

/// What to render.
#[derive(Clone, Debug)]
pub struct RenderOptions {
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Maximum scattering events.
    pub max_depth: u32,
    /// Sampling seed.
    pub seed: u64,
    /// Camera prim path; empty for the scene's first camera.
    pub camera: String,
    /// AOVs besides beauty.
    pub aovs: Vec<String>,
    /// Render threads on the server; 0 for all.
    pub threads: u32,
    /// Stream intermediate passes as f16.
    pub progressive_f16: bool,
    /// Kulla-Conty energy compensation.
    pub energy_compensation: bool,
    /// Owen-scrambled Sobol (true, the default) or independent random numbers.
    pub sobol: bool,
    /// Firefly clamp on indirect contributions; `None` (the default) is off.
    pub clamp_indirect: Option<f32>,
    /// Adaptive sampling's relative-error target; `None` (the default) is off.
    pub noise_threshold: Option<f32>,
    /// Caustic avoidance (biased, less noisy) instead of full path tracing.
    pub avoid_caustics: bool,
    /// Run every effect whether or not the scene calls for it (benchmarking the plan).
    pub force_all_effects: bool,
    /// Mip-map textures by the ray's footprint.
    pub texture_filtering: bool,
    /// Adaptive splitting in the light tree.
    pub light_splitting: bool,
    /// Most lights per shading point when splitting (0: the server's default, 8).
    pub light_split_budget: u32,
    /// Width over height of a pixel; 0 for the scene's RenderSettings, else square.
    pub pixel_aspect: f32,
    /// Edge of the server's render tiles (the regions the final stats count samples in); 0
    /// for the server's default, 64.
    pub tile_size: u32,
    /// Block edge of the coarse first-look passes (a viewport's option; 0, the default, is
    /// off: final renders start with full passes).
    pub coarse_start: u32,
    /// The first sample index of every pixel to render (a slice of a split render, or the
    /// rest of a resumed one); `spp` is where it ends. Must start a pass.
    pub first_sample: u32,
    /// Stream exact pass sums instead of pixels (for [`crate::film::ExactFilm`]).
    pub stream_film: bool,
    /// Denoise the final image on the client (`crate::denoise`): adds `beauty_denoised`
    /// and asks for the albedo and normal AOVs it is guided by.
    pub denoise: bool,
}

impl Default for RenderOptions {
    fn default() -> Self {
        RenderOptions {
            width: 256,
            height: 256,
            spp: 64,
            max_depth: 8,
            seed: 0,
            camera: String::new(),
            aovs: Vec::new(),
            threads: 0,
            progressive_f16: true,
            energy_compensation: true,
            texture_filtering: true,
            light_splitting: true,
            light_split_budget: 0,
            sobol: true,
            clamp_indirect: None,
            noise_threshold: None,
            avoid_caustics: false,
            force_all_effects: false,
            pixel_aspect: 0.0,
            tile_size: 0,
            coarse_start: 0,
            first_sample: 0,
            stream_film: false,
            denoise: false,
        }
    }
}

/// Everything a render produced.
#[derive(Clone, Debug, Default)]
pub struct RenderReport {
    /// The final image.
    pub image: Image,
    /// The `Started` event.
    pub started: pb::Started,
    /// The `Finished` event.
    pub finished: pb::Finished,
    /// Scene versions of every `Restarted` event.
    pub restarts: Vec<u64>,
    /// Every `Progress` event, in order.
    pub progress: Vec<pb::Progress>,
    /// Tile events received.
    pub tiles: u64,
}

/// Turns a gRPC status into an error a person can read.
pub fn status_error(s: tonic::Status) -> anyhow::Error {
    ServerError { code: s.code(), message: s.message().to_string() }.into()
}

/// A status the server answered with, kept typed so that a caller (the CLI's exit status) can
/// tell a request that will never succeed from a failure worth retrying.
#[derive(Debug, thiserror::Error)]
#[error("server: {message}")]
pub struct ServerError {
    /// The gRPC status code.
    pub code: tonic::Code,
    /// The server's message, naming the prim or field at fault.
    pub message: String,
}

/// How a client proves who it is: a bearer token, and for `https://` URLs the certificate
/// authority that signed the server's certificate.
#[derive(Clone, Debug, Default)]
pub struct Credentials {
    /// Sent as `authorization: Bearer TOKEN` on every call.
    pub token: Option<String>,
    /// PEM certificate of the authority to trust (`None`: the system's roots are not built
    /// in, so an `https://` URL needs one).
    pub ca_pem: Option<Vec<u8>>,
}

impl Credentials {
    /// From the environment: `TESSERA_TOKEN` and `TESSERA_TLS_CA` (a PEM file).
    pub fn from_env() -> Result<Self> {
        let token = std::env::var("TESSERA_TOKEN").ok().filter(|t| !t.is_empty());
        let ca_pem = match std::env::var_os("TESSERA_TLS_CA") {
            Some(p) => Some(std::fs::read(&p).with_context(|| format!("TESSERA_TLS_CA: cannot read {}", p.to_string_lossy()))?),
            None => None,
        };
        Ok(Credentials { token, ca_pem })
    }
}

/// Puts the bearer token on every call.
#[derive(Clone)]
pub struct BearerToken(Option<tonic::metadata::MetadataValue<tonic::metadata::Ascii>>);

impl tonic::service::Interceptor for BearerToken {
    fn call(&mut self, mut req: tonic::Request<()>) -> Result<tonic::Request<()>, tonic::Status> {
        if let Some(v) = &self.0 {
            req.metadata_mut().insert("authorization", v.clone());
        }
        Ok(req)
    }
}

type Client = RenderClient<InterceptedService<Channel, BearerToken>>;

/// Connects to `url` with `creds`.
async fn client(url: &str, creds: &Credentials) -> Result<Client> {
    let mut endpoint = Channel::from_shared(url.to_string())?;
    if url.starts_with("https://") {
        let mut tls = ClientTlsConfig::new();
        if let Some(ca) = &creds.ca_pem {
            tls = tls.ca_certificate(Certificate::from_pem(ca));
        }
        endpoint = endpoint.tls_config(tls)?;
    }
    let channel = endpoint.connect().await.with_context(|| format!("cannot connect to {url}"))?;
    let token = match &creds.token {
        Some(t) => Some(format!("Bearer {t}").parse().context("the token must be printable ASCII")?),
        None => None,
    };
    Ok(RenderClient::with_interceptor(channel, BearerToken(token)).max_decoding_message_size(64 << 20))
}

/// A session on a render server.
pub struct Connection {
    client: Client,
    /// The session id.
    pub session: String,
}

impl Connection {
    /// Connects and opens a session, with credentials from the environment
    /// ([`Credentials::from_env`]).
    pub async fn connect(url: &str, client_name: &str) -> Result<Self> {
        Self::connect_with(url, client_name, &Credentials::from_env()?).await
    }

    /// Connects with `creds` and opens a session.
    pub async fn connect_with(url: &str, client_name: &str, creds: &Credentials) -> Result<Self> {
        let mut client = client(url, creds).await?;
        let session = client
            .create_session(pb::CreateSessionRequest { client_name: client_name.into() })
            .await
            .map_err(status_error)?
            .into_inner()
            .session_id;
        Ok(Connection { client, session })
    }

    /// Joins an existing session (a second connection, e.g. to edit while rendering).
    pub async fn attach(url: &str, session: &str) -> Result<Self> {
        Self::attach_with(url, session, &Credentials::from_env()?).await
    }

    /// [`Self::attach`] with `creds`.
    pub async fn attach_with(url: &str, session: &str, creds: &Credentials) -> Result<Self> {
        Ok(Connection { client: client(url, creds).await?, session: session.to_string() })
    }

    /// What the session holds and has done.
    pub async fn stats(&mut self) -> Result<pb::SessionStats> {
        let req = pb::GetSessionStatsRequest { session_id: self.session.clone() };
        Ok(self.client.get_session_stats(req).await.map_err(status_error)?.into_inner())
    }

    /// The server's capabilities.
    pub async fn capabilities(&mut self) -> Result<pb::Capabilities> {
        Ok(self.client.get_capabilities(pb::GetCapabilitiesRequest {}).await.map_err(status_error)?.into_inner())
    }

    /// Sends one transaction of deltas.
    pub async fn sync(&mut self, items: Vec<pb::sync_request::Item>) -> Result<pb::SyncResponse> {
        let reqs = crate::sync::requests(&self.session, items);
        Ok(self.client.sync(tokio_stream::iter(reqs)).await.map_err(status_error)?.into_inner())
    }

    /// Syncs a whole translation, uploading only the texture files the server does not
    /// already hold.
    pub async fn sync_scene(&mut self, t: &crate::usd::Translation) -> Result<pb::SyncResponse> {
        let missing = self.missing_textures(t.textures.keys().cloned().collect()).await?;
        self.sync(crate::sync::scene_sync(t, |h| missing.iter().any(|m| m == h))).await
    }

    /// Those of the texture content hashes the server does not hold.
    pub async fn missing_textures(&mut self, hashes: Vec<String>) -> Result<Vec<String>> {
        if hashes.is_empty() {
            return Ok(Vec::new());
        }
        let req = pb::MissingTexturesRequest { content_hashes: hashes };
        Ok(self.client.missing_textures(req).await.map_err(status_error)?.into_inner().content_hashes)
    }

    /// Asks the server to stop this session's render.
    pub async fn cancel(&mut self) -> Result<bool> {
        Ok(self
            .client
            .cancel(pb::CancelRequest { session_id: self.session.clone() })
            .await
            .map_err(status_error)?
            .into_inner()
            .was_rendering)
    }

    /// Starts a render and returns its raw event stream (for callers that consume events
    /// at their own pace, like the Python package).
    pub async fn render_stream(&mut self, opts: &RenderOptions) -> Result<tonic::Streaming<pb::RenderEvent>> {
        let settings = pb::RenderSettings {
            width: opts.width,
            height: opts.height,
            spp: opts.spp,
            max_depth: opts.max_depth,
            seed: opts.seed,
            camera_path: opts.camera.clone(),
            aovs: opts.aovs.clone(),
            tile_size: opts.tile_size,
            progressive_format: if opts.progressive_f16 { pb::PixelFormat::F16 } else { pb::PixelFormat::F32 } as i32,
            threads: opts.threads,
            disable_energy_compensation: !opts.energy_compensation,
            sampler: if opts.sobol { pb::Sampler::Sobol } else { pb::Sampler::Independent } as i32,
            clamp_indirect: opts.clamp_indirect.unwrap_or(0.0),
            noise_threshold: opts.noise_threshold.unwrap_or(0.0),
            caustics: if opts.avoid_caustics { pb::Caustics::Avoid } else { pb::Caustics::Full } as i32,
            force_all_effects: opts.force_all_effects,
            disable_texture_filtering: !opts.texture_filtering,
            disable_light_splitting: !opts.light_splitting,
            pixel_aspect: opts.pixel_aspect,
            light_split_budget: opts.light_split_budget,
            coarse_start: opts.coarse_start,
            first_sample: opts.first_sample,
            stream_film: opts.stream_film,
        };
        Ok(self
            .client
            .render(pb::RenderRequest { session_id: self.session.clone(), settings: Some(settings) })
            .await
            .map_err(status_error)?
            .into_inner())
    }

    /// Renders, calling `on_event` for every event, and assembles the final image.
    pub async fn render(&mut self, opts: &RenderOptions, on_event: impl FnMut(&pb::render_event::Event)) -> Result<RenderReport> {
        self.render_into(opts, None, on_event, |_| Ok(())).await
    }

    /// [`Self::render`] that, with `film` (and `opts.stream_film`), adds the streamed pass
    /// sums to it and calls `on_pass` after every completed pass (to checkpoint it); the
    /// report's image is then resolved from the film when it starts at sample 0.
    pub async fn render_into(
        &mut self,
        opts: &RenderOptions,
        mut film: Option<&mut crate::film::ExactFilm>,
        mut on_event: impl FnMut(&pb::render_event::Event),
        mut on_pass: impl FnMut(&crate::film::ExactFilm) -> Result<()>,
    ) -> Result<RenderReport> {
        let mut stream = self.render_stream(opts).await?;
        let mut report = RenderReport::default();
        while let Some(event) = stream.message().await.map_err(status_error)? {
            let Some(event) = event.event else { continue };
            on_event(&event);
            use pb::render_event::Event;
            match event {
                Event::Started(s) => {
                    report.image = Image { width: s.width, height: s.height, ..Default::default() };
                    report.started = s;
                }
                Event::Tile(t) => {
                    let data = tessera_wire::convert::tile_pixels(&t).map_err(status_error)?;
                    report.image.write_tile(&t.aov, crate::output::TileRect::of(&t), t.channels, &data);
                    report.tiles += 1;
                }
                Event::Film(t) => {
                    film.as_deref_mut().context("the server streamed film sums nobody asked for")?.add(&t)?;
                    report.tiles += 1;
                }
                Event::Progress(p) => {
                    if let Some(film) = film.as_deref_mut() {
                        film.pass_done(p.spp);
                        on_pass(film)?;
                    }
                    report.progress.push(p);
                }
                Event::Restarted(r) => {
                    if let Some(film) = film.as_deref_mut() {
                        film.clear();
                    }
                    report.restarts.push(r.scene_version);
                }
                Event::Finished(f) => {
                    if let Some(film) = film.filter(|f| f.range.start == 0 && opts.stream_film) {
                        report.image = film.resolve(&report.started.aovs)?;
                    }
                    report.finished = f;
                    return Ok(report);
                }
            }
        }
        anyhow::bail!("the server closed the render stream before it finished")
    }

    /// Closes the session.
    pub async fn close(mut self) -> Result<()> {
        self.close_session().await
    }

    /// Closes the session, keeping the connection (a holder that cannot give it up, such as a
    /// Python session object, closes through this).
    pub async fn close_session(&mut self) -> Result<()> {
        self.client.close_session(pb::CloseSessionRequest { session_id: self.session.clone() }).await.map_err(status_error)?;
        Ok(())
    }
}
