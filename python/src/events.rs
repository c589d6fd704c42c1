//! A render's events, read from the gRPC stream on the client's runtime and handed to Python
//! one at a time: the tiles of all AOVs of one rect and pass grouped into one event.

use std::sync::{Arc, Mutex};

use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use tessera::remote::{Connection, Credentials, RenderOptions, status_error};
use tessera_proto::v1 as pb;
use tokio::runtime::Runtime;
use tokio::sync::mpsc;

use crate::py_err;

/// Events buffered between the stream and Python: a reader that stops reading makes the
/// server wait, then drop the render (its stall timeout), rather than fill this process.
const BUFFER: usize = 64;

/// Each AOV of one rect: its name, channels and f32 pixels.
type Layers = Vec<(String, u32, Vec<f32>)>;

/// One event for Python.
enum Event {
    Raw(pb::render_event::Event),
    /// One rect and pass: every AOV's f32 pixels, at full resolution.
    Tile {
        tile: pb::Tile,
        layers: Vec<(String, u32, Vec<f32>)>,
    },
}

/// A render in progress; iterating yields its events as dicts, ending after `finished`.
#[pyclass(name = "_RenderStream")]
pub struct RenderStream {
    rx: Mutex<mpsc::Receiver<anyhow::Result<Event>>>,
    task: tokio::task::JoinHandle<()>,
}

impl RenderStream {
    /// Opens a second connection to the session (edits keep using the first) and starts the
    /// render on it.
    pub async fn start(rt: &Arc<Runtime>, url: String, session: String, creds: Credentials, opts: RenderOptions) -> anyhow::Result<Self> {
        let mut conn = Connection::attach_with(&url, &session, &creds).await?;
        let stream = conn.render_stream(&opts).await?;
        let (tx, rx) = mpsc::channel(BUFFER);
        let task = rt.spawn(async move {
            let _conn = conn;
            pump(stream, tx).await;
        });
        Ok(RenderStream { rx: Mutex::new(rx), task })
    }
}

impl Drop for RenderStream {
    fn drop(&mut self) {
        // Dropping the stream closes it; the server cancels the render.
        self.task.abort();
    }
}

/// Reads the stream, grouping each rect's tiles across AOVs, until it ends or Python stops
/// listening.
async fn pump(mut stream: tonic::Streaming<pb::RenderEvent>, tx: mpsc::Sender<anyhow::Result<Event>>) {
    let mut aovs = 1usize;
    let mut group: Option<(pb::Tile, Layers)> = None;
    loop {
        let item = match stream.message().await {
            Ok(Some(pb::RenderEvent { event: Some(e) })) => e,
            Ok(Some(_)) => continue,
            Ok(None) => return,
            Err(s) => {
                tx.send(Err(status_error(s))).await.ok();
                return;
            }
        };
        let mut out = Vec::new();
        match item {
            pb::render_event::Event::Tile(mut t) => {
                let pixels = match tessera_wire::convert::tile_pixels(&t) {
                    Ok(p) => p,
                    Err(s) => {
                        tx.send(Err(status_error(s))).await.ok();
                        return;
                    }
                };
                let same = group.as_ref().is_some_and(|(g, _)| {
                    (g.x, g.y, g.width, g.height, g.pass_index, g.pixel_size) == (t.x, t.y, t.width, t.height, t.pass_index, t.pixel_size)
                });
                if !same && let Some((tile, layers)) = group.take() {
                    out.push(Event::Tile { tile, layers });
                }
                let layer = (std::mem::take(&mut t.aov), t.channels, pixels);
                t.pixels = Vec::new();
                group.get_or_insert_with(|| (t, Vec::new())).1.push(layer);
                if group.as_ref().is_some_and(|(_, l)| l.len() >= aovs) {
                    let (tile, layers) = group.take().expect("just checked");
                    out.push(Event::Tile { tile, layers });
                }
            }
            other => {
                if let pb::render_event::Event::Started(s) = &other {
                    aovs = s.aovs.len().max(1);
                }
                if let Some((tile, layers)) = group.take() {
                    out.push(Event::Tile { tile, layers });
                }
                out.push(Event::Raw(other));
            }
        }
        for e in out {
            if tx.send(Ok(e)).await.is_err() {
                return;
            }
        }
    }
}

#[pymethods]
impl RenderStream {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    /// The next event as a dict, with the GIL released while waiting for it.
    fn __next__(&self, py: Python<'_>) -> PyResult<Option<Py<PyDict>>> {
        // Python's thread is outside the runtime, so it may block on the channel directly.
        let next = py.detach(|| self.rx.lock().expect("one reader").blocking_recv());
        match next {
            None => Ok(None),
            Some(Err(e)) => Err(py_err(e)),
            Some(Ok(e)) => to_dict(py, e).map(Some),
        }
    }
}

fn to_dict(py: Python<'_>, e: Event) -> PyResult<Py<PyDict>> {
    use pb::render_event::Event as E;
    let d = PyDict::new(py);
    match e {
        Event::Tile { tile: t, layers } => {
            d.set_item("type", "tile")?;
            for (k, v) in [
                ("x", t.x),
                ("y", t.y),
                ("width", t.width),
                ("height", t.height),
                ("pass_index", t.pass_index),
                ("samples", t.samples),
                ("pixel_size", t.pixel_size.max(1)),
            ] {
                d.set_item(k, v)?;
            }
            let l = PyDict::new(py);
            for (aov, channels, pixels) in layers {
                let bytes: Vec<u8> = pixels.iter().flat_map(|v| v.to_le_bytes()).collect();
                l.set_item(aov, (channels, PyBytes::new(py, &bytes)))?;
            }
            d.set_item("layers", l)?;
        }
        Event::Raw(E::Started(s)) => {
            d.set_item("type", "started")?;
            d.set_item("width", s.width)?;
            d.set_item("height", s.height)?;
            d.set_item("aovs", s.aovs)?;
            d.set_item("pass_spp", s.pass_spp)?;
            d.set_item("warnings", s.warnings)?;
            d.set_item("scene_version", s.scene_version)?;
            d.set_item("prim_paths", s.prim_paths)?;
            let plan = PyList::empty(py);
            for p in s.plan {
                let e = PyDict::new(py);
                e.set_item("effect", p.effect)?;
                e.set_item("reason", p.reason)?;
                e.set_item("prims", p.prims)?;
                plan.append(e)?;
            }
            d.set_item("plan", plan)?;
        }
        Event::Raw(E::Progress(p)) => {
            d.set_item("type", "progress")?;
            d.set_item("pass_index", p.pass_index)?;
            d.set_item("spp", p.spp)?;
            d.set_item("percent", p.percent)?;
            d.set_item("estimated_noise", p.estimated_noise)?;
            d.set_item("elapsed_seconds", p.elapsed_seconds)?;
            d.set_item("rays_per_second", p.rays_per_second)?;
            d.set_item("active_pixels", p.active_pixels)?;
        }
        Event::Raw(E::Restarted(r)) => {
            d.set_item("type", "restarted")?;
            d.set_item("scene_version", r.scene_version)?;
        }
        Event::Raw(E::Finished(f)) => {
            d.set_item("type", "finished")?;
            d.set_item("seconds", f.seconds)?;
            d.set_item("spp", f.spp)?;
            d.set_item("rays", f.rays)?;
            d.set_item("paths", f.paths)?;
            d.set_item("estimated_noise", f.estimated_noise)?;
            d.set_item("cancelled", f.cancelled)?;
            d.set_item("mean_spp", f.mean_spp)?;
        }
        Event::Raw(E::Tile(_) | E::Film(_)) => d.set_item("type", "unexpected")?,
    }
    Ok(d.unbind())
}
