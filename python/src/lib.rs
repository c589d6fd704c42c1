//! `tessera._native`: the Rust client behind the `tessera` Python package. The same USD
//! translation, sync and tile decoding the CLI uses; `tessera/__init__.py` wraps it in
//! Python types (dataclasses, NumPy arrays).

mod events;
mod options;

use std::path::PathBuf;
use std::sync::{Arc, Mutex};

use pyo3::create_exception;
use pyo3::exceptions::PyException;
use pyo3::prelude::*;
use pyo3::types::{PyBytes, PyDict, PyList};
use tessera::live::{LiveSession, SentPrim};
use tessera::remote::{Connection, Credentials, ServerError};
use tokio::runtime::Runtime;

create_exception!(_native, TesseraError, PyException, "A render server or scene error, with the server's message.");

/// Turns an error into a `TesseraError` carrying its whole chain (the server's message names
/// the prim and field).
fn py_err(e: anyhow::Error) -> PyErr {
    TesseraError::new_err(format!("{e:#}"))
}

/// A connection to a render server: the one at `url`, or an embedded one in this process.
#[pyclass(name = "_Client")]
struct Client {
    rt: Arc<Runtime>,
    url: String,
    creds: Credentials,
    embedded: Mutex<Option<tessera_server::EmbeddedServer>>,
}

#[pymethods]
impl Client {
    #[new]
    #[pyo3(signature = (url=None, token=None))]
    fn new(py: Python<'_>, url: Option<String>, token: Option<String>) -> PyResult<Self> {
        let rt = Arc::new(tokio::runtime::Builder::new_multi_thread().enable_all().build().map_err(|e| py_err(e.into()))?);
        let mut creds = Credentials::from_env().map_err(py_err)?;
        if token.is_some() {
            creds.token = token;
        }
        let embedded = match &url {
            Some(_) => None,
            None => Some(py.detach(|| rt.block_on(tessera_server::EmbeddedServer::start())).map_err(py_err)?),
        };
        let url = url.unwrap_or_else(|| embedded.as_ref().expect("started above").url());
        Ok(Client { rt, url, creds, embedded: Mutex::new(embedded) })
    }

    /// The server's URL (the embedded server's loopback address when none was given).
    #[getter]
    fn url(&self) -> String {
        self.url.clone()
    }

    /// Opens a session on the server.
    #[pyo3(signature = (name="tessera-python"))]
    fn session(&self, py: Python<'_>, name: &str) -> PyResult<Session> {
        let conn = py.detach(|| self.rt.block_on(Connection::connect_with(&self.url, name, &self.creds))).map_err(py_err)?;
        let id = conn.session.clone();
        Ok(Session {
            rt: self.rt.clone(),
            url: self.url.clone(),
            creds: self.creds.clone(),
            id,
            live: Arc::new(tokio::sync::Mutex::new(LiveSession::new(conn))),
            closed: std::sync::atomic::AtomicBool::new(false),
        })
    }

    /// Stops the embedded server, if this client started one.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        if let Some(server) = self.embedded.lock().expect("not poisoned").take() {
            py.detach(|| self.rt.block_on(server.stop())).map_err(py_err)?;
        }
        Ok(())
    }
}

/// One session: the scene it holds, edits as deltas, renders as event streams.
#[pyclass(name = "_Session")]
struct Session {
    rt: Arc<Runtime>,
    url: String,
    creds: Credentials,
    id: String,
    live: Arc<tokio::sync::Mutex<LiveSession>>,
    /// Set once `close` has run.
    closed: std::sync::atomic::AtomicBool,
}

impl Session {
    /// Runs an edit on the live session with the GIL released, returning what it sent.
    fn edit<F, Fut>(&self, py: Python<'_>, f: F) -> PyResult<Py<PyList>>
    where
        F: FnOnce(Arc<tokio::sync::Mutex<LiveSession>>) -> Fut + Send,
        Fut: std::future::Future<Output = anyhow::Result<Vec<SentPrim>>> + Send,
    {
        let live = self.live.clone();
        let sent = py.detach(|| self.rt.block_on(f(live))).map_err(py_err)?;
        sent_list(py, &sent)
    }
}

#[pymethods]
impl Session {
    /// The session id.
    #[getter]
    fn id(&self) -> String {
        self.id.clone()
    }

    /// Closes the session on the server, freeing its scene and its place among the server's
    /// sessions (an unclosed one lingers until the server's idle timeout). Closing twice, or
    /// after the server reaped it, does nothing.
    fn close(&self, py: Python<'_>) -> PyResult<()> {
        if self.closed.swap(true, std::sync::atomic::Ordering::SeqCst) {
            return Ok(());
        }
        let live = self.live.clone();
        match py.detach(|| self.rt.block_on(async move { live.lock().await.conn.close_session().await })) {
            Err(e) if e.downcast_ref::<ServerError>().is_some_and(|s| s.code == tonic::Code::NotFound) => Ok(()),
            other => other.map_err(py_err),
        }
    }

    /// Translates a USD file at `frame` and syncs it: everything the first time, afterwards
    /// only the prims that changed. Returns (what was sent, warnings).
    #[pyo3(signature = (path, frame=None))]
    fn sync_usd(&self, py: Python<'_>, path: PathBuf, frame: Option<f64>) -> PyResult<(Py<PyList>, Vec<String>)> {
        let live = self.live.clone();
        let (sent, warnings) =
            py.detach(|| self.rt.block_on(async move { live.lock().await.sync_usd(&path, frame).await })).map_err(py_err)?;
        Ok((sent_list(py, &sent)?, warnings))
    }

    /// Moves a mesh, light or camera: `matrix` is 4 rows of 4, translation in the last column.
    fn set_transform(&self, py: Python<'_>, prim_path: String, matrix: [[f64; 4]; 4]) -> PyResult<Py<PyList>> {
        self.edit(py, |live| async move { live.lock().await.set_transform(&prim_path, matrix).await })
    }

    /// Changes a camera's lens (focal_length, f_stop, focus_distance, horizontal_aperture,
    /// vertical_aperture) or its exposure (stops).
    #[pyo3(signature = (path, **params))]
    fn set_camera(&self, py: Python<'_>, path: String, params: Option<&Bound<'_, PyDict>>) -> PyResult<Py<PyList>> {
        let params: Vec<(String, f64)> =
            kwargs(params)?.into_iter().map(|(k, v)| v.extract::<f64>().map(|v| (k, v))).collect::<PyResult<_>>()?;
        self.edit(py, |live| async move { live.lock().await.set_camera(&path, &params).await })
    }

    /// Changes a light's inputs (intensity, exposure, diffuse, specular, color).
    #[pyo3(signature = (path, **params))]
    fn set_light_params(&self, py: Python<'_>, path: String, params: Option<&Bound<'_, PyDict>>) -> PyResult<Py<PyList>> {
        let params: Vec<(String, Vec<f64>)> = kwargs(params)?
            .into_iter()
            .map(|(k, v)| v.extract::<f64>().map(|x| vec![x]).or_else(|_| v.extract::<Vec<f64>>()).map(|v| (k, v)))
            .collect::<PyResult<_>>()?;
        self.edit(py, |live| async move { live.lock().await.set_light_params(&path, &params).await })
    }

    /// Links a light: it illuminates only the prims at or under `illuminates` and only those
    /// at or under `shadowed_by` cast its shadows (None: every prim).
    #[pyo3(signature = (path, illuminates=None, shadowed_by=None))]
    fn set_light_links(
        &self,
        py: Python<'_>,
        path: String,
        illuminates: Option<Vec<String>>,
        shadowed_by: Option<Vec<String>>,
    ) -> PyResult<Py<PyList>> {
        self.edit(py, |live| async move { live.lock().await.set_light_links(&path, illuminates, shadowed_by).await })
    }

    /// Sets a shader input of a material: a float, three floats, or a string.
    fn set_material_input(
        &self,
        py: Python<'_>,
        material_path: String,
        shader: String,
        input: String,
        value: &Bound<'_, PyAny>,
    ) -> PyResult<Py<PyList>> {
        let value = options::param_value(&input, value)?;
        self.edit(py, |live| async move { live.lock().await.set_material_input(&material_path, &shader, &input, value).await })
    }

    /// Starts a progressive render; returns a stream of event dicts.
    #[pyo3(signature = (width, height, spp=64, aovs=None, **settings))]
    fn render(
        &self,
        py: Python<'_>,
        width: u32,
        height: u32,
        spp: u32,
        aovs: Option<Vec<String>>,
        settings: Option<&Bound<'_, PyDict>>,
    ) -> PyResult<events::RenderStream> {
        let opts = options::render_options(width, height, spp, aovs.unwrap_or_default(), &kwargs(settings)?)?;
        let (url, id, creds) = (self.url.clone(), self.id.clone(), self.creds.clone());
        py.detach(|| self.rt.block_on(events::RenderStream::start(&self.rt, url, id, creds, opts))).map_err(py_err)
    }

    /// Stops the session's render; true when one was running.
    fn cancel(&self, py: Python<'_>) -> PyResult<bool> {
        py.detach(|| {
            self.rt.block_on(async {
                let mut conn = Connection::attach_with(&self.url, &self.id, &self.creds).await?;
                conn.cancel().await
            })
        })
        .map_err(py_err)
    }
}

/// The process's OIDN device, created on first use (creating one costs about 0.3 s).
static DENOISER: Mutex<Option<tessera::denoise::Denoiser>> = Mutex::new(None);

/// Denoises `color` (float32 bytes, `channels` per pixel, RGB first) guided by `albedo` and
/// `normal` (float32 RGB bytes) with Open Image Denoise; returns float32 RGB bytes.
#[pyfunction]
fn denoise(
    py: Python<'_>,
    width: usize,
    height: usize,
    color: &[u8],
    channels: usize,
    albedo: &[u8],
    normal: &[u8],
) -> PyResult<Py<PyBytes>> {
    let floats = |b: &[u8], per: usize, what: &str| -> PyResult<Vec<f32>> {
        if b.len() != width * height * per * 4 {
            return Err(TesseraError::new_err(format!("denoise: {what} holds {} bytes, not {width}x{height}x{per} float32", b.len())));
        }
        Ok(b.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
    };
    if channels < 3 {
        return Err(TesseraError::new_err(format!("denoise: colour needs 3 or 4 channels, not {channels}")));
    }
    let (color, albedo, normal) = (floats(color, channels, "colour")?, floats(albedo, 3, "albedo")?, floats(normal, 3, "normal")?);
    let out = py
        .detach(|| {
            let mut held = DENOISER.lock().expect("not poisoned");
            if held.is_none() {
                *held = Some(tessera::denoise::Denoiser::new(0)?);
            }
            held.as_ref().expect("just made").denoise((width, height), &color, channels, &albedo, &normal)
        })
        .map_err(py_err)?;
    let bytes: Vec<u8> = out.iter().flat_map(|v| v.to_le_bytes()).collect();
    Ok(PyBytes::new(py, &bytes).unbind())
}

/// A kwargs dict as (name, value) pairs.
fn kwargs<'py>(d: Option<&Bound<'py, PyDict>>) -> PyResult<Vec<(String, Bound<'py, PyAny>)>> {
    d.map(|d| d.iter().map(|(k, v)| Ok((k.extract::<String>()?, v))).collect()).unwrap_or(Ok(Vec::new()))
}

/// What a sync sent, as a list of dicts {path, kind, dirty, chunks}.
fn sent_list(py: Python<'_>, sent: &[SentPrim]) -> PyResult<Py<PyList>> {
    let list = PyList::empty(py);
    for s in sent {
        let d = PyDict::new(py);
        d.set_item("path", &s.path)?;
        d.set_item("kind", s.kind)?;
        d.set_item("dirty", s.dirty.clone())?;
        d.set_item("chunks", s.chunks)?;
        list.append(d)?;
    }
    Ok(list.unbind())
}

#[pymodule]
fn _native(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Client>()?;
    m.add_class::<Session>()?;
    m.add_class::<events::RenderStream>()?;
    m.add_function(wrap_pyfunction!(denoise, m)?)?;
    m.add("TesseraError", m.py().get_type::<TesseraError>())?;
    Ok(())
}
