//! UsdGeom cameras.

use anyhow::Result;

use super::*;

impl Reader<'_> {
    pub(super) fn camera(&mut self, prim: &Prim, p: &str) -> Result<()> {
        let time = self.time;
        let d = CameraDesc::default();
        let float = |name: &str, default: f32| -> Result<f32> {
            Ok(get(prim, name, time)?.as_ref().and_then(values::scalar).map_or(default, |v| v as f32))
        };
        let orthographic = get(prim, "projection", time)?.as_ref().and_then(values::token).is_some_and(|t| t == "orthographic");
        let f_stop = float("fStop", 0.0)?;
        if orthographic && f_stop > 0.0 {
            self.out.warnings.push(format!("{p}: depth of field is not simulated for orthographic cameras; fStop is ignored"));
        }
        let clip = get(prim, "clippingRange", time)?.as_ref().and_then(values::vec2).unwrap_or([d.near as f64, d.far as f64]);
        let desc = CameraDesc {
            transform: self.affine(prim, p)?,
            focal_length: float("focalLength", d.focal_length)?,
            horizontal_aperture: float("horizontalAperture", d.horizontal_aperture)?,
            vertical_aperture: float("verticalAperture", d.vertical_aperture)?,
            horizontal_aperture_offset: float("horizontalApertureOffset", 0.0)?,
            vertical_aperture_offset: float("verticalApertureOffset", 0.0)?,
            near: clip[0] as f32,
            far: clip[1] as f32,
            orthographic,
            f_stop,
            focus_distance: float("focusDistance", 0.0)?,
            shutter_open: float("shutter:open", 0.0)?,
            shutter_close: float("shutter:close", 0.0)?,
            motion: self.motion(prim, p)?,
            exposure: self.exposure_stops(prim, p)?,
        };
        self.out.cameras.push((p.to_string(), desc));
        Ok(())
    }

    /// The camera's exposure in stops, from UsdGeomCamera's `exposure` (stops) and its
    /// physical exposure (`exposure:time` × `exposure:iso` × `exposure:responsivity` /
    /// (100 × `exposure:fStop`²), as `ComputeLinearExposureScale` gives it: 1 at the schema's
    /// defaults). A scale that is not positive, or past ±64 stops, is warned and not applied.
    fn exposure_stops(&mut self, prim: &Prim, p: &str) -> Result<f32> {
        let time = self.time;
        let read =
            |name: &str, default: f64| -> Result<f64> { Ok(get(prim, name, time)?.as_ref().and_then(values::scalar).unwrap_or(default)) };
        let (stops, iso, seconds, f_stop, responsivity) = (
            read("exposure", 0.0)?,
            read("exposure:iso", 100.0)?,
            read("exposure:time", 1.0)?,
            read("exposure:fStop", 1.0)?,
            read("exposure:responsivity", 1.0)?,
        );
        let physical = seconds * iso * responsivity / (100.0 * f_stop * f_stop);
        let total = stops + physical.log2();
        if total.is_finite() && total.abs() <= render_core::camera::MAX_EXPOSURE_STOPS as f64 {
            return Ok(total as f32);
        }
        self.out.warnings.push(format!(
            "{p}: exposure {stops}, exposure:iso {iso}, exposure:time {seconds}, exposure:fStop {f_stop} and exposure:responsivity {responsivity} give a scale of {:e}; the image is not scaled",
            stops.exp2() * physical
        ));
        Ok(0.0)
    }
}
