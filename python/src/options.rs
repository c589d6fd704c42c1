//! Python keyword arguments to render options and shader parameter values, each refused with
//! a message naming the argument.

use glam::Vec3;
use pyo3::prelude::*;
use render_core::material::ParamValue;
use tessera::remote::RenderOptions;

use crate::TesseraError;

fn bad(name: &str, why: &str) -> PyErr {
    TesseraError::new_err(format!("render setting {name}: {why}"))
}

/// Render options from the arguments of `Session.render`.
pub fn render_options(
    width: u32,
    height: u32,
    spp: u32,
    aovs: Vec<String>,
    settings: &[(String, Bound<'_, PyAny>)],
) -> PyResult<RenderOptions> {
    let mut o = RenderOptions { width, height, spp, aovs, ..Default::default() };
    for (name, v) in settings {
        let float = || v.extract::<f32>().map_err(|_| bad(name, "expects a number"));
        let int = || v.extract::<u32>().map_err(|_| bad(name, "expects a non-negative integer"));
        let flag = || v.extract::<bool>().map_err(|_| bad(name, "expects True or False"));
        let text = || v.extract::<String>().map_err(|_| bad(name, "expects a string"));
        match name.as_str() {
            "max_depth" => o.max_depth = int()?,
            "seed" => o.seed = v.extract::<u64>().map_err(|_| bad(name, "expects a non-negative integer"))?,
            "camera" => o.camera = text()?,
            "threads" => o.threads = int()?,
            "tile_size" => o.tile_size = int()?,
            "coarse_start" => o.coarse_start = int()?,
            "light_split_budget" => o.light_split_budget = int()?,
            "clamp" => o.clamp_indirect = Some(float()?),
            "noise_threshold" => o.noise_threshold = Some(float()?),
            "pixel_aspect" => o.pixel_aspect = float()?,
            "energy_compensation" => o.energy_compensation = flag()?,
            "texture_filtering" => o.texture_filtering = flag()?,
            "light_splitting" => o.light_splitting = flag()?,
            "progressive_f16" => o.progressive_f16 = flag()?,
            "caustics" => {
                o.avoid_caustics = match text()?.as_str() {
                    "avoid" => true,
                    "full" => false,
                    other => return Err(bad(name, &format!("'{other}' is neither 'full' nor 'avoid'"))),
                }
            }
            "sampler" => {
                o.sobol = match text()?.as_str() {
                    "sobol" => true,
                    "independent" => false,
                    other => return Err(bad(name, &format!("'{other}' is neither 'sobol' nor 'independent'"))),
                }
            }
            _ => {
                return Err(bad(
                    name,
                    "unknown (max_depth, seed, camera, threads, tile_size, coarse_start, light_split_budget, clamp, noise_threshold, pixel_aspect, energy_compensation, texture_filtering, light_splitting, progressive_f16, caustics, sampler)",
                ));
            }
        }
    }
    Ok(o)
}

/// A shader input's value: a bool, a number, three numbers or a string.
pub fn param_value(input: &str, v: &Bound<'_, PyAny>) -> PyResult<ParamValue> {
    if let Ok(b) = v.extract::<bool>() {
        return Ok(ParamValue::Bool(b));
    }
    if let Ok(x) = v.extract::<f32>() {
        return Ok(ParamValue::Float(x));
    }
    if let Ok([r, g, b]) = v.extract::<[f32; 3]>() {
        return Ok(ParamValue::Float3(Vec3::new(r, g, b)));
    }
    if let Ok(s) = v.extract::<String>() {
        return Ok(ParamValue::String(s));
    }
    Err(TesseraError::new_err(format!("input {input}: expects a bool, a number, three numbers or a string")))
}
