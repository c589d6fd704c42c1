//! Transform motion over the camera's shutter: a prim's world transform sampled at evenly
//! spaced times from `shutter:open` to `shutter:close` (frame-relative, USD's convention),
//! with xformOps evaluated at each time as USD interpolates them (linearly by component,
//! orientations slerped). The renderer interpolates linearly between the samples
//! (`render_core::motion`), so more samples follow a rotation's arc more closely: a quality
//! knob, `--motion-samples`.

use anyhow::{Context, Result};

use super::*;

/// Samples over the shutter when none are asked for: a rotation of 90° over the shutter
/// then strays from its arc by at most r·(1 − cos(11.25°)) = 2% of its radius.
pub const DEFAULT_MOTION_SAMPLES: usize = 5;

/// The shutter interval the stage asks for: `options` (frame-relative) when given, else the
/// render camera's (the one the RenderSettings names, else the first camera), as absolute
/// times around `time`; `None` when it is closed.
pub(super) fn shutter_interval(stage: &Stage, paths: &[sdf::Path], time: f64, options: &LoadOptions) -> Result<Option<(f64, f64)>> {
    let (open, close) = match options.shutter {
        Some(s) => s,
        None => {
            let Some(camera) = render_camera(stage, paths)? else { return Ok(None) };
            let prim = stage.prim(camera);
            let read = |name: &str| -> Result<f64> {
                Ok(get(&prim, name, TimeCode::new(time))?.as_ref().and_then(values::scalar).filter(|v| v.is_finite()).unwrap_or(0.0))
            };
            (read("shutter:open")?, read("shutter:close")?)
        }
    };
    Ok((close > open).then_some((time + open, time + close)))
}

/// The camera a render uses by default: the first RenderSettings' camera, else the first camera.
fn render_camera(stage: &Stage, paths: &[sdf::Path]) -> Result<Option<sdf::Path>> {
    let type_of = |p: &sdf::Path| stage.prim(p.clone()).type_name().ok().flatten().map(|t| t.as_str().to_string());
    for p in paths.iter().filter(|p| type_of(p).as_deref() == Some("RenderSettings")) {
        if let Some(c) = render_settings::camera_target(&stage.prim(p.clone()))? {
            return Ok(Some(sdf::Path::new(&c)?));
        }
    }
    Ok(paths.iter().find(|p| type_of(p).as_deref() == Some("Camera")).cloned())
}

/// USD's velocity-based motion: `base` points `dt` seconds on, moved by their `velocities`
/// plus half their `accelerations` (when given) times dt².
pub(super) fn extrapolate(base: &[Vec3], velocities: &[Vec3], accelerations: Option<&[Vec3]>, dt: f32) -> Vec<Vec3> {
    let moved = base.iter().zip(velocities).enumerate().map(|(i, (p, v))| {
        let a = accelerations.map_or(Vec3::ZERO, |a| a[i]);
        *p + *v * dt + a * (0.5 * dt * dt)
    });
    moved.collect()
}

impl Reader<'_> {
    /// The motion samples' times: `--motion-samples` evenly spaced from shutter open to close
    /// (none when the shutter is closed). Transforms, instances, skeletons and points are all
    /// sampled at these.
    pub(super) fn shutter_times(&self) -> Vec<TimeCode> {
        let Some((open, close)) = self.shutter else { return Vec::new() };
        let n = self.motion_samples.max(2);
        (0..n).map(|i| TimeCode::new(open + (close - open) * i as f64 / (n - 1) as f64)).collect()
    }

    /// The prim's world transform at evenly spaced times over the shutter; empty when the
    /// shutter is closed or the prim does not move over it.
    pub(super) fn motion(&mut self, prim: &Prim, p: &str) -> Result<Vec<Affine3A>> {
        let times = self.shutter_times();
        if times.is_empty() {
            return Ok(Vec::new());
        }
        let samples = times
            .into_iter()
            .map(|t| {
                let m = self.world_at(prim.path(), t)?;
                to_affine(&m).with_context(|| format!("{p}: xformOps compose to a non-finite transform at time {}", t.value()))
            })
            .collect::<Result<Vec<_>>>()?;
        if samples.iter().all(|m| *m == samples[0]) {
            return Ok(Vec::new());
        }
        if let Some(i) = samples.iter().position(|m| render_core::geometry::Transform::new(*m).is_none()) {
            anyhow::bail!("{p}: xformOps compose to a singular transform at motion sample {i} of the shutter");
        }
        Ok(samples)
    }
}
