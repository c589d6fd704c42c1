//! UsdLux lights and their shaping.

use anyhow::Result;

use super::*;

impl Reader<'_> {
    pub(super) fn light(&mut self, prim: &Prim, p: &str, type_name: &str, visible: bool) -> Result<()> {
        let time = self.time;
        let input = |name: &str| light_input(prim, name, time);
        let float = |name: &str, default: f32| light_float(prim, name, default, time);
        let kind = match type_name {
            "SphereLight" => LightKind::Sphere { radius: float("radius", 0.5)? },
            "RectLight" => LightKind::Rect { width: float("width", 1.0)?, height: float("height", 1.0)? },
            "DiskLight" => LightKind::Disk { radius: float("radius", 0.5)? },
            "CylinderLight" => LightKind::Cylinder { radius: float("radius", 0.5)?, length: float("length", 1.0)? },
            "DistantLight" => LightKind::Distant { angle_degrees: float("angle", 0.53)? },
            _ => LightKind::Dome,
        };
        let mut texture = None;
        match (type_name, input("texture:file")?) {
            ("DomeLight" | "DomeLight_1", Some(Value::AssetPath(a))) if !a.is_empty() => {
                let format = input("texture:format")?.as_ref().and_then(values::token).unwrap_or_else(|| "automatic".into());
                if format != "automatic" && format != "latlong" {
                    self.out.warnings.push(format!(
                        "{p}: texture:format '{format}' is not supported (only latlong); the map is read as latitude-longitude"
                    ));
                }
                match self.texture_param(p, "texture:file", &a) {
                    ParamValue::Texture { hash, source } => texture = Some(render_core::texture::TextureRef { hash, source }),
                    ParamValue::Udim { source, .. } => self.out.warnings.push(format!(
                        "{p}: texture:file '{source}' is a UDIM set, which an environment map cannot be; the light's constant colour is used"
                    )),
                    _ => {}
                }
            }
            ("RectLight", Some(_)) => self
                .out
                .warnings
                .push(format!("{p}: inputs:texture:file on a RectLight is not supported yet; the light's constant colour is used")),
            _ => {}
        }
        let mut transform = self.affine(prim, p)?;
        let mut motion = self.motion(prim, p)?;
        if type_name == "DomeLight_1" {
            // `poleAxis` (UsdLux DomeLight_1): the dome's top pole starts along the stage's up
            // axis ("scene", the fallback), +Y or +Z; a Z pole is the +Y pole turned 90° about
            // +X, applied to the dome alone.
            let pole = get(prim, "poleAxis", time)?.as_ref().and_then(values::token).unwrap_or_else(|| "scene".into());
            let z_pole = match pole.as_str() {
                "Z" => true,
                "Y" => false,
                "scene" => self.out.z_up,
                other => {
                    self.out.warnings.push(format!("{p}: poleAxis '{other}' is not scene, Y or Z; using scene"));
                    self.out.z_up
                }
            };
            if z_pole {
                let turn = glam::Affine3A::from_rotation_x(std::f32::consts::FRAC_PI_2);
                transform *= turn;
                motion.iter_mut().for_each(|m| *m *= turn);
            }
        }
        let [light_link, shadow_link] = self.light_links(p);
        // UsdLux: DistantLight's intensity defaults to 50000, every other light's to 1.
        let common = LightInputs::read(prim, if type_name == "DistantLight" { 50000.0 } else { 1.0 }, time)?;
        let desc = LightDesc {
            light_link,
            shadow_link,
            kind,
            transform,
            intensity: common.intensity,
            exposure: common.exposure,
            color: common.color,
            normalize: common.normalize,
            // `tessera:visibleToCamera` (default on, as UsdLux lights are seen): DCCs whose lights
            // camera rays do not see (Blender's default) say so with it.
            visible_to_camera: get(prim, "tessera:visibleToCamera", time)?.as_ref().and_then(values::scalar).is_none_or(|v| v != 0.0),
            shaping: self.shaping(prim, p, type_name)?,
            diffuse: common.diffuse,
            specular: common.specular,
            texture,
            motion,
        };
        if !visible {
            return Ok(());
        }
        self.out.lights.push((p.to_string(), desc));
        Ok(())
    }

    /// The light a gprim is, when `MeshLightAPI` or `LightAPI` is applied to it: its inputs,
    /// links and `light:materialSyncMode` (fallback `materialGlowTintsLight` under
    /// `MeshLightAPI`, `noMaterialResponse` under plain `LightAPI`).
    pub(super) fn gprim_light(&mut self, prim: &Prim, p: &str) -> Result<Option<MeshLight>> {
        let Some(api) = self.gprim_light_api(prim)? else { return Ok(None) };
        let time = self.time;
        let fallback = if api == "MeshLightAPI" { MaterialSync::GlowTintsLight } else { MaterialSync::NoMaterialResponse };
        let token = get(prim, "light:materialSyncMode", time)?.as_ref().and_then(values::token);
        let sync = match token.as_deref() {
            None => fallback,
            Some(t) if let Some(&(_, sync)) = SYNC_TOKENS.iter().find(|(name, _)| *name == t) => sync,
            Some(other) => {
                self.out.warnings.push(format!("{p}: light:materialSyncMode '{other}' is not one UsdLux defines; using {fallback:?}"));
                fallback
            }
        };
        let common = LightInputs::read(prim, 1.0, time)?;
        // By the prim's path: the parts of a mesh split by GeomSubsets (`p` names each part)
        // carry the mesh's links.
        let [light_link, shadow_link] = self.light_links(prim.path().as_str());
        Ok(Some(MeshLight {
            intensity: common.intensity,
            exposure: common.exposure,
            color: common.color,
            normalize: common.normalize,
            diffuse: common.diffuse,
            specular: common.specular,
            sync,
            light_link,
            shadow_link,
            // `p` names a part when the mesh is split by its GeomSubsets.
            part_of: (p != prim.path().as_str()).then(|| prim.path().to_string()),
        }))
    }

    /// `MeshLightAPI` or `LightAPI` when applied to `prim`, a gprim rendered as a mesh
    /// ([`lit_as_mesh`]), else None.
    pub(super) fn gprim_light_api(&mut self, prim: &Prim) -> Result<Option<&'static str>> {
        self.reported_names.update(self.stage);
        if !self.reported_names.apis || !prim.type_name()?.is_some_and(|t| lit_as_mesh(t.as_str())) {
            return Ok(None);
        }
        let applied = prim.api_schemas()?;
        Ok(["MeshLightAPI", "LightAPI"].into_iter().find(|api| applied.iter().any(|a| a.as_str() == *api)))
    }

    /// `ShapingAPI` inputs when any is authored (on the area lights it applies to); IES
    /// profiles are reported as unsupported.
    pub(super) fn shaping(&mut self, prim: &Prim, p: &str, type_name: &str) -> Result<Option<render_core::light::Shaping>> {
        let time = self.time;
        let read = |name: &str| get(prim, &format!("inputs:shaping:{name}"), time);
        let (angle, softness, focus, tint) = (read("cone:angle")?, read("cone:softness")?, read("focus")?, read("focusTint")?);
        if read("ies:file")?.is_some() {
            self.out.warnings.push(format!("{p}: IES profiles (inputs:shaping:ies:file) are not supported yet and are ignored"));
        }
        if angle.is_none() && softness.is_none() && focus.is_none() && tint.is_none() {
            return Ok(None);
        }
        if matches!(type_name, "DomeLight" | "DomeLight_1" | "DistantLight") {
            self.out.warnings.push(format!("{p}: ShapingAPI has no meaning for a {type_name} and is ignored"));
            return Ok(None);
        }
        let d = render_core::light::Shaping::default();
        let scalar = |v: &Option<Value>, default: f32| v.as_ref().and_then(values::scalar).map_or(default, |x| x as f32);
        Ok(Some(render_core::light::Shaping {
            cone_angle: scalar(&angle, d.cone_angle),
            cone_softness: scalar(&softness, d.cone_softness),
            focus: scalar(&focus, d.focus),
            focus_tint: tint.as_ref().and_then(values::vec3).unwrap_or(d.focus_tint),
        }))
    }
}

/// UsdLux's `light:materialSyncMode` tokens and what each asks for.
pub const SYNC_TOKENS: [(&str, MaterialSync); 3] = [
    ("materialGlowTintsLight", MaterialSync::GlowTintsLight),
    ("independent", MaterialSync::Independent),
    ("noMaterialResponse", MaterialSync::NoMaterialResponse),
];

/// A UsdLux input of `prim` at `time`; pre-2021 files spell them without the `inputs:` prefix.
fn light_input(prim: &Prim, name: &str, time: TimeCode) -> Result<Option<Value>> {
    match get(prim, &format!("inputs:{name}"), time)? {
        Some(v) => Ok(Some(v)),
        None => get(prim, name, time),
    }
}

/// A scalar UsdLux input, or `default` when it is not authored.
fn light_float(prim: &Prim, name: &str, default: f32, time: TimeCode) -> Result<f32> {
    Ok(light_input(prim, name, time)?.as_ref().and_then(values::scalar).map_or(default, |v| v as f32))
}

/// The inputs every UsdLux light has (`LightAPI`'s), with the schema's fallbacks.
struct LightInputs {
    intensity: f32,
    exposure: f32,
    /// `inputs:color`, times the colour temperature's RGB when that is enabled.
    color: Vec3,
    normalize: bool,
    diffuse: f32,
    specular: f32,
}

impl LightInputs {
    /// Read at `time`; `intensity` is the light type's fallback for `inputs:intensity`.
    fn read(prim: &Prim, intensity: f32, time: TimeCode) -> Result<LightInputs> {
        let input = |name: &str| light_input(prim, name, time);
        let float = |name: &str, default: f32| light_float(prim, name, default, time);
        // UsdLux: the colour temperature multiplies `color` when enabled (default 6500 K).
        let temperature = (input("enableColorTemperature")?.as_ref().and_then(values::scalar).unwrap_or(0.0) != 0.0)
            .then(|| float("colorTemperature", 6500.0))
            .transpose()?;
        Ok(LightInputs {
            intensity: float("intensity", intensity)?,
            exposure: float("exposure", 0.0)?,
            color: input("color")?.as_ref().and_then(values::vec3).unwrap_or(Vec3::ONE)
                * temperature.map_or(Vec3::ONE, render_core::light::blackbody::blackbody_rgb),
            normalize: input("normalize")?.as_ref().and_then(values::scalar).unwrap_or(0.0) != 0.0,
            diffuse: float("diffuse", 1.0)?,
            specular: float("specular", 1.0)?,
        })
    }
}
