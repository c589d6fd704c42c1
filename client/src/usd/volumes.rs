//! `UsdVolVolume` prims: their `field:*` relationships to `OpenVDBAsset` fields, the grids
//! read from the VDB files (with the `vdb-rs` crate), made dense over their active voxels, and
//! the bound material's `tessera:Volume` shader (Blender's Principled Volume inputs).

use anyhow::{Context, Result};
use glam::IVec3;
use render_core::volume::{VolumeDesc, VolumeShading, VoxelGrid};

use super::render_settings::valid_targets;
use super::*;

/// The scalar fields a volume renders; any other `field:` relationship but a colour one is
/// reported.
const FIELDS: [&str; 2] = ["density", "temperature"];

/// The names a colour field goes by: Blender's `color`, Houdini's `Cd`.
const COLOUR_FIELDS: [&str; 2] = ["color", "Cd"];

/// A value a grid holds as the reader reads it: a float (density, temperature) or a vec3s
/// (colour).
trait GridValue: bytemuck::Pod + Default {
    /// OpenVDB's name for the tree (files saved as half floats add `_HalfFloat`).
    const TREE: &'static str;
}

impl GridValue for f32 {
    const TREE: &'static str = "Tree_float_5_4_3";
}

impl GridValue for [f32; 3] {
    const TREE: &'static str = "Tree_vec3s_5_4_3";
}

/// The grids a Volume's `field:` relationships name, read.
#[derive(Default)]
struct Fields {
    /// Density and temperature, by field name.
    scalar: std::collections::BTreeMap<String, SparseGrid<f32>>,
    /// The colour field's relationship name and grid.
    colour: Option<(String, SparseGrid<[f32; 3]>)>,
}

/// One grid of a VDB file as read: its active voxels (position, value, edge in voxels) and
/// its index-to-object transform.
struct SparseGrid<T> {
    voxels: Vec<(IVec3, T, i32)>,
    index_to_object: Affine3A,
    /// The file it came from, resolved, and the grid's name there.
    file: String,
    name: String,
}

impl<T: GridValue> SparseGrid<T> {
    /// Lists it in `source` as the grid of `field`, for `tessera inspect`.
    fn record_in(&self, source: &mut VolumeSource, field: &str) {
        source.fields.push((field.to_string(), self.file.clone(), self.name.clone()));
        source.active_voxels.push(self.active_voxels());
    }

    /// Its active voxels, a tile counting each voxel it covers.
    fn active_voxels(&self) -> u64 {
        self.voxels.iter().map(|&(_, _, size)| (size as u64).pow(3)).sum()
    }

    /// The inclusive box of its active voxels (None when it has none).
    fn bounds(&self) -> Option<(IVec3, IVec3)> {
        self.voxels.iter().map(|&(p, _, size)| (p, p + IVec3::splat(size - 1))).reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
    }

    /// Its values over the box `(lo, hi)`, dense with x fastest, the default (0) where inactive.
    fn dense(&self, (lo, hi): (IVec3, IVec3)) -> Vec<T> {
        let dims = (hi - lo + IVec3::ONE).as_uvec3();
        let mut values = vec![T::default(); VoxelGrid::voxel_count(dims) as usize];
        let at = |p: IVec3| {
            let l = (p - lo).as_uvec3();
            l.x as usize + dims.x as usize * (l.y as usize + dims.y as usize * l.z as usize)
        };
        for &(p, v, size) in &self.voxels {
            let (a, b) = (p.max(lo), (p + IVec3::splat(size - 1)).min(hi));
            for z in a.z..=b.z {
                for y in a.y..=b.y {
                    for x in a.x..=b.x {
                        values[at(IVec3::new(x, y, z))] = v;
                    }
                }
            }
        }
        values
    }
}

impl SparseGrid<f32> {
    /// Its values over the box `(lo, hi)` as the renderer's grid.
    fn voxel_grid(&self, bounds: (IVec3, IVec3)) -> VoxelGrid {
        VoxelGrid { origin: bounds.0, dims: (bounds.1 - bounds.0 + IVec3::ONE).as_uvec3(), values: self.dense(bounds) }
    }
}

impl SparseGrid<[f32; 3]> {
    /// Its red, green and blue over the box `(lo, hi)`, one renderer grid each.
    fn channel_grids(&self, bounds: (IVec3, IVec3)) -> [Arc<VoxelGrid>; 3] {
        let rgb = self.dense(bounds);
        let dims = (bounds.1 - bounds.0 + IVec3::ONE).as_uvec3();
        [0, 1, 2].map(|c| Arc::new(VoxelGrid { origin: bounds.0, dims, values: rgb.iter().map(|v| v[c]).collect() }))
    }
}

/// Reads the grid `name` of the VDB file at `path` as values of type `T`. The crate panics on
/// what it does not support (some transforms, older files): caught and reported as an error.
fn read_vdb<T: GridValue>(path: &std::path::Path, name: &str) -> Result<SparseGrid<T>> {
    let file = std::fs::File::open(path).with_context(|| format!("cannot open '{}'", path.display()))?;
    let mut grid = read_grid(std::io::BufReader::new(file), name)?;
    grid.file = path.display().to_string();
    Ok(grid)
}

/// Reads the grid `name` of a VDB stream (the grid's `file` left empty).
fn read_grid<T: GridValue>(stream: impl std::io::Read + std::io::Seek, name: &str) -> Result<SparseGrid<T>> {
    let read = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| -> Result<SparseGrid<T>> {
        let mut reader = vdb_rs::VdbReader::new(stream).map_err(|e| anyhow::anyhow!("{e}"))?;
        let Some(descriptor) = reader.grid_descriptors.get(name) else {
            anyhow::bail!("it has no grid '{name}' (it has {})", reader.available_grids().join(", "));
        };
        // The reader reinterprets bytes as `T`: a grid of another type must not reach it.
        let tree = descriptor.grid_type.trim_end_matches("_HalfFloat");
        if tree != T::TREE {
            anyhow::bail!("grid '{name}' is a {}, where this field needs a {}", descriptor.grid_type, T::TREE);
        }
        let grid = reader.read_grid::<T>(name).map_err(|e| anyhow::anyhow!("grid '{name}': {e}"))?;
        let voxels =
            grid.iter().map(|(p, v, level)| (IVec3::from_array(p.to_array().map(|x| x as i32)), v, level.scale() as i32)).collect();
        Ok(SparseGrid { voxels, index_to_object: index_to_object(&grid.transform), file: String::new(), name: name.to_string() })
    }));
    read.unwrap_or_else(|_| Err(anyhow::anyhow!("the VDB reader failed on it (a corrupt grid tree)")))
}

/// A VDB transform as an affine map from index space to the grid's object space.
fn index_to_object(map: &vdb_rs::Map) -> Affine3A {
    let (scale, translation) = match map {
        vdb_rs::Map::UniformScaleMap { voxel_size, .. } => (voxel_size.to_array(), [0.0; 3]),
        vdb_rs::Map::ScaleTranslateMap { voxel_size, translation, .. } => (voxel_size.to_array(), translation.to_array()),
        vdb_rs::Map::TranslationMap { translation } => ([1.0; 3], translation.to_array()),
        // A projective last row (none in an affine map) is dropped; the commit rejects a
        // singular or non-finite map, naming the volume.
        vdb_rs::Map::AffineMap { index_to_world } => {
            return Affine3A::from_mat4(glam::Mat4::from_cols_array(&index_to_world.to_cols_array().map(|x| x as f32)));
        }
    };
    Affine3A::from_scale_rotation_translation(
        Vec3::from_array(scale.map(|x| x as f32)),
        glam::Quat::IDENTITY,
        Vec3::from_array(translation.map(|x| x as f32)),
    )
}

impl Reader<'_> {
    /// A Volume prim: its density (temperature and colour) grids and shading.
    pub(super) fn volume(&mut self, prim: &Prim, p: &str, visible: bool) -> Result<()> {
        let Fields { scalar: mut grids, colour } = self.volume_fields(prim, p)?;
        let (world, motion) = (self.affine(prim, p)?, self.motion(prim, p)?);
        let mut source = VolumeSource { path: p.to_string(), world, motion, fields: Vec::new(), active_voxels: Vec::new() };
        for (field, g) in &grids {
            g.record_in(&mut source, field);
        }
        if let Some((field, g)) = &colour {
            g.record_in(&mut source, field);
        }
        let Some(density) = grids.remove("density") else {
            self.out.warnings.push(format!("{p}: no field:density relationship; the volume is not rendered"));
            self.out.skipped.push(p.to_string());
            return Ok(());
        };
        let temperature = grids.remove("temperature").filter(|t| self.aligned(p, "temperature", t.index_to_object, &density));
        let colour = colour.filter(|(field, c)| self.aligned(p, field, c.index_to_object, &density)).map(|(_, c)| c);
        // The block spans the density's and temperature's active voxels (a colour matters only
        // where there is density). With no active voxel at all, an empty box.
        let bounds = [density.bounds(), temperature.as_ref().and_then(SparseGrid::bounds)]
            .into_iter()
            .flatten()
            .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
            .unwrap_or((IVec3::ZERO, IVec3::splat(-1)));
        let voxels = VoxelGrid::voxel_count((bounds.1 - bounds.0 + IVec3::ONE).max(IVec3::ZERO).as_uvec3());
        if voxels > render_core::volume::grid::MAX_VOXELS {
            anyhow::bail!(
                "{p}: the grids' active voxels span {voxels} voxels, over the {} one volume may have",
                render_core::volume::grid::MAX_VOXELS
            );
        }
        let desc = VolumeDesc {
            density: Arc::new(density.voxel_grid(bounds)),
            temperature: temperature.map(|t| Arc::new(t.voxel_grid(bounds))),
            color: colour.map(|c| c.channel_grids(bounds)),
            index_to_world: source.world * density.index_to_object,
            shading: self.volume_shading(prim, p)?,
            motion: source.motion.iter().map(|world| *world * density.index_to_object).collect(),
            link_collections: self.link_collections(prim.path()),
        };
        if visible {
            self.out.volumes.push((p.to_string(), desc));
            self.out.volume_sources.push(source);
        }
        Ok(())
    }

    /// The grids a Volume's `field:` relationships name, read. A colour field that cannot be
    /// used is reported and the volume renders without it; a second colour field is reported.
    fn volume_fields(&mut self, prim: &Prim, p: &str) -> Result<Fields> {
        let mut fields = Fields::default();
        for rel in prim.relationships()? {
            let rel = rel.path().property_suffix().trim_start_matches('.').to_string();
            let Some(field) = rel.strip_prefix("field:").map(str::to_string) else { continue };
            let is_colour = COLOUR_FIELDS.contains(&field.as_str());
            if !is_colour && !FIELDS.contains(&field.as_str()) {
                self.out
                    .warnings
                    .push(format!("{p}: field '{field}' is not rendered (only density, temperature and a colour field, color or Cd)"));
                continue;
            }
            let Some(target) = valid_targets(prim, p, &rel)?.into_iter().next() else { continue };
            if !is_colour {
                fields.scalar.insert(field.clone(), self.field(p, &field, &target)?);
            } else if let Some((first, _)) = &fields.colour {
                self.out.warnings.push(format!("{p}: field '{field}' is not used: field '{first}' already gives the colour"));
            } else {
                match self.field::<[f32; 3]>(p, &field, &target) {
                    Ok(grid) => fields.colour = Some((field, grid)),
                    Err(e) => {
                        self.out.warnings.push(format!("{p}: field '{field}' is not used, the volume renders without its colour: {e:#}"))
                    }
                }
            }
        }
        Ok(fields)
    }

    /// Whether a field's voxels are the density grid's (the renderer samples every field in the
    /// density's index space); reported when not.
    fn aligned(&mut self, p: &str, field: &str, index_to_object: Affine3A, density: &SparseGrid<f32>) -> bool {
        let same = index_to_object.abs_diff_eq(density.index_to_object, 1e-6);
        if !same {
            self.out.warnings.push(format!("{p}: the {field} grid's voxels are not the density grid's; it is not used"));
        }
        same
    }

    /// The grid an `OpenVDBAsset` field prim names: its file and `fieldName`.
    fn field<T: GridValue>(&mut self, p: &str, field: &str, target: &sdf::Path) -> Result<SparseGrid<T>> {
        let asset = self.stage.prim(target.clone());
        let kind = asset.type_name()?.map(|t| t.as_str().to_string()).unwrap_or_default();
        if kind != "OpenVDBAsset" {
            anyhow::bail!("{p}: field:{field} targets {target}, a '{kind}', not an OpenVDBAsset");
        }
        let file = match get(&asset, "filePath", self.time)? {
            Some(Value::AssetPath(a)) if !a.is_empty() => a,
            _ => anyhow::bail!("{target}: attribute 'filePath' is missing or not an asset path"),
        };
        let resolved = file.resolved_path().map(|r| r.to_string()).unwrap_or_else(|| file.as_str().to_string());
        let name = get(&asset, "fieldName", self.time)?.as_ref().and_then(values::token).unwrap_or_else(|| field.to_string());
        read_vdb(std::path::Path::new(&resolved), &name).with_context(|| format!("{target}: filePath '{}'", file.as_str()))
    }

    /// The bound material's `outputs:volume` shader, read as a `tessera:Volume`; Blender's
    /// Principled Volume defaults without one.
    fn volume_shading(&mut self, prim: &Prim, p: &str) -> Result<VolumeShading> {
        let d = VolumeShading::default();
        let Some(material) = self.bound_material(prim)? else { return Ok(d) };
        let m = self.stage.prim(sdf::Path::new(&material)?);
        let Some(source) = ["outputs:volume", "outputs:tessera:volume"]
            .into_iter()
            .find_map(|o| m.attribute(o).connections().ok().and_then(|c| c.into_iter().next()))
        else {
            self.out.warnings.push(format!("{p}: material {material} has no outputs:volume; Principled Volume defaults are used"));
            return Ok(d);
        };
        let shader = self.stage.prim(source.prim_path());
        let id = get(&shader, "info:id", self.time)?.as_ref().and_then(values::token).unwrap_or_default();
        if id != "tessera:Volume" {
            self.out.warnings.push(format!(
                "{}: volume shader '{id}' is not supported (tessera:Volume is); Principled Volume defaults are used",
                shader.path()
            ));
            return Ok(d);
        }
        let time = self.time;
        let float = |name: &str, default: f32| -> Result<f32> {
            Ok(get(&shader, &format!("inputs:{name}"), time)?.as_ref().and_then(values::scalar).map_or(default, |x| x as f32))
        };
        let color = |name: &str, default: Vec3| -> Result<Vec3> {
            Ok(get(&shader, &format!("inputs:{name}"), time)?.as_ref().and_then(values::vec3).unwrap_or(default))
        };
        Ok(VolumeShading {
            density: float("density", d.density)?,
            color: color("color", d.color)?,
            anisotropy: float("anisotropy", d.anisotropy)?,
            emission: color("emissionColor", Vec3::ONE)? * float("emissionStrength", 0.0)?,
            blackbody_intensity: float("blackbodyIntensity", d.blackbody_intensity)?,
            blackbody_tint: color("blackbodyTint", d.blackbody_tint)?,
            temperature: float("temperature", d.temperature)?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A corrupt VDB file is an error, never an abort: every 8-byte window of tinted.vdb (which
    /// holds float, vec3s and half-float grids) overwritten in turn with sizes far too large,
    /// negative or all ones, each grid read. vdb-rs 0.6 as released aborted the process on the
    /// first huge size (an allocation of 2^63 bytes); third_party/vdb-rs checks each size first.
    #[test]
    fn a_corrupt_vdb_file_is_an_error_never_an_abort() {
        let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../fixtures/usd/volumes/tinted.vdb");
        let clean = std::fs::read(path).expect("the fixture");
        let read_all = |bytes: &[u8]| -> [bool; 4] {
            let cursor = || std::io::Cursor::new(bytes);
            [
                read_grid::<f32>(cursor(), "density").is_ok(),
                read_grid::<f32>(cursor(), "density_half").is_ok(),
                read_grid::<[f32; 3]>(cursor(), "Cd").is_ok(),
                read_grid::<[f32; 3]>(cursor(), "Cd_half").is_ok(),
            ]
        };
        assert_eq!(read_all(&clean), [true; 4], "the clean file reads");
        let patterns = [[0xff; 8], 0x7fff_ffff_ffff_fff0u64.to_le_bytes(), (-(1i64 << 40)).to_le_bytes()];
        let mut failed = 0;
        // Every 29th offset (1,778 windows over headers, masks, sizes and payloads) keeps this
        // to seconds in a debug build; a release run over every offset survived too
        // (2026-12-03).
        for offset in (0..clean.len() - 8).step_by(29) {
            for pattern in &patterns {
                let mut bytes = clean.clone();
                bytes[offset..offset + 8].copy_from_slice(pattern);
                failed += read_all(&bytes).iter().filter(|ok| !**ok).count();
            }
        }
        assert!(failed > 0, "some corruptions are reported");
    }
}
