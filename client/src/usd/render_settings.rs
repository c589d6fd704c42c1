//! UsdRender settings and products: camera, resolution, output file and AOVs.

use anyhow::Result;

use super::*;

/// The targets of relationship `rel` of `prim` (at `p`); a malformed one is an error naming
/// the relationship (openusd recurses without end on some, see [`well_formed_path`]).
pub(super) fn valid_targets(prim: &Prim, p: &str, rel: &str) -> Result<Vec<sdf::Path>> {
    let targets = prim.relationship(rel).targets()?;
    if let Some(bad) = targets.iter().find(|t| !well_formed_path(t.as_str())) {
        anyhow::bail!("{p}: relationship '{rel}' targets '{}', which is not a valid path", bad.as_str());
    }
    Ok(targets)
}

/// The first well-formed target of a RenderSettings' or RenderProduct's `camera`.
pub(super) fn camera_target(prim: &Prim) -> Result<Option<String>> {
    Ok(prim.relationship("camera").targets()?.first().map(|t| t.as_str().to_string()).filter(|t| well_formed_path(t)))
}

/// Tessera's AOV for a `RenderVar` `sourceName` (Hydra's names, and ours).
pub(super) fn aov_of_source(source: &str) -> Option<&'static str> {
    Some(match source {
        "color" | "Ci" | "beauty" => "beauty",
        "albedo" => "albedo",
        "normal" | "N" => "normal",
        "depth" | "z" | "Z" => "depth",
        "position" | "P" => "position",
        "primId" => "primId",
        "diffuse" => "diffuse",
        "specular" => "specular",
        "transmission" => "transmission",
        "subsurface" => "subsurface",
        "diffuse_direct" => "diffuse_direct",
        "diffuse_indirect" => "diffuse_indirect",
        "specular_direct" => "specular_direct",
        "specular_indirect" => "specular_indirect",
        "transmission_direct" => "transmission_direct",
        "transmission_indirect" => "transmission_indirect",
        "subsurface_direct" => "subsurface_direct",
        "subsurface_indirect" => "subsurface_indirect",
        "emission" => "emission",
        "sampleCount" => "sampleCount",
        "variance" => "variance",
        _ => return None,
    })
}

/// What a `RenderSettings` prim asks for.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderSettingsDesc {
    /// The prim's path.
    pub path: String,
    /// Its `camera` relationship's target.
    pub camera: Option<String>,
    /// `resolution`.
    pub resolution: Option<(u32, u32)>,
    /// `pixelAspectRatio`, when authored.
    pub pixel_aspect: Option<f32>,
    /// The `products` it names, in order.
    pub products: Vec<RenderProductDesc>,
}

/// A `UsdRender` `RenderProduct`: an output file and the AOVs (`RenderVar`s) it holds.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct RenderProductDesc {
    /// The prim's path.
    pub path: String,
    /// `productName`: the file to write.
    pub name: Option<String>,
    /// Its own `camera`, overriding the settings'.
    pub camera: Option<String>,
    /// Its own `resolution`, overriding the settings'.
    pub resolution: Option<(u32, u32)>,
    /// Our AOV names for its `orderedVars`' `sourceName`s (beauty is always written).
    pub aovs: Vec<String>,
}

impl Reader<'_> {
    /// A `UsdRender` `RenderSettings` prim: kept when it is the one the stage designates
    /// (`renderSettingsPrimPath`) or, without one, the first met.
    pub(super) fn render_settings(&mut self, prim: &Prim, p: &str) -> Result<()> {
        let designated = self.stage.stage_metadata("renderSettingsPrimPath")?.as_ref().and_then(values::token);
        let chosen = match &designated {
            Some(d) => d == p,
            None => self.out.render_settings.is_none(),
        };
        if !chosen {
            return Ok(());
        }
        let camera = camera_target(prim)?;
        let resolution = self.resolution(prim, p)?;
        let pixel_aspect = match get(prim, "pixelAspectRatio", self.time)?.as_ref().and_then(values::scalar) {
            Some(a) if a.is_finite() && a > 0.0 => Some(a as f32),
            Some(a) => anyhow::bail!("{p}: attribute 'pixelAspectRatio' is {a}; expected a positive number"),
            None => None,
        };
        let mut products = Vec::new();
        for target in valid_targets(prim, p, "products")? {
            let tp = target.as_str().to_string();
            let product = self.stage.prim(target);
            if product.type_name()?.is_none_or(|t| t.as_str() != "RenderProduct") {
                self.out.warnings.push(format!("{p}: products target {tp}, which is not a RenderProduct; ignored"));
                continue;
            }
            products.push(self.render_product(&product, &tp)?);
        }
        if products.len() > 1 {
            self.out.warnings.push(format!(
                "{p}: {} render products; only the first ({}) is written (one EXR per render)",
                products.len(),
                products[0].path
            ));
        }
        self.out.render_settings = Some(RenderSettingsDesc { path: p.to_string(), camera, resolution, pixel_aspect, products });
        Ok(())
    }

    /// `resolution` of a RenderSettings or RenderProduct prim.
    pub(super) fn resolution(&self, prim: &Prim, p: &str) -> Result<Option<(u32, u32)>> {
        Ok(match get(prim, "resolution", self.time)? {
            Some(Value::Vec2i(r)) if r.x > 0 && r.y > 0 => Some((r.x as u32, r.y as u32)),
            Some(v) => anyhow::bail!("{p}: attribute 'resolution' is {v:?}; expected two positive integers"),
            None => None,
        })
    }

    /// A `RenderProduct`: `productName`, its own camera and resolution, and the AOVs of its
    /// `orderedVars` (a `sourceName` we do not produce is a warning naming the RenderVar).
    pub(super) fn render_product(&mut self, prim: &Prim, p: &str) -> Result<RenderProductDesc> {
        let name = get(prim, "productName", self.time)?.as_ref().and_then(values::token).filter(|n| !n.is_empty());
        let camera = camera_target(prim)?;
        let resolution = self.resolution(prim, p)?;
        let mut aovs = Vec::new();
        for target in valid_targets(prim, p, "orderedVars")? {
            let vp = target.as_str().to_string();
            let var = self.stage.prim(target);
            let source = get(&var, "sourceName", self.time)?.as_ref().and_then(values::token).unwrap_or_default();
            match aov_of_source(&source) {
                Some("beauty") => {}
                Some(aov) if !aovs.iter().any(|a| a == aov) => aovs.push(aov.to_string()),
                Some(_) => {}
                None => self.out.warnings.push(format!("{vp}: RenderVar sourceName '{source}' is not an AOV Tessera renders; skipped")),
            }
        }
        Ok(RenderProductDesc { path: p.to_string(), name, camera, resolution, aovs })
    }
}
