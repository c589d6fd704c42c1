//! Image output: a multi-layer OpenEXR (linear, scene-referred) and a tone-mapped PNG
//! preview beside it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use exr::prelude::*;

/// An assembled image: each AOV's pixels, row-major, channels interleaved.
#[derive(Clone, Debug, Default)]
pub struct Image {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// AOV name → (channels, pixels).
    pub layers: BTreeMap<String, (u32, Vec<f32>)>,
}

/// Where a tile lies in an image, in pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TileRect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

impl TileRect {
    /// The rectangle a streamed tile covers.
    pub fn of(tile: &tessera_proto::v1::Tile) -> Self {
        TileRect { x: tile.x, y: tile.y, width: tile.width, height: tile.height }
    }
}

impl Image {
    /// Copies in a tile of `channels` interleaved channels covering `rect` (what falls
    /// outside the image is dropped).
    pub fn write_tile(&mut self, aov: &str, rect: TileRect, channels: u32, data: &[f32]) {
        let (width, height) = (self.width, self.height);
        let TileRect { x, y, width: w, height: h } = rect;
        let (c, layer) = self.layers.entry(aov.to_string()).or_insert_with(|| (channels, vec![0.0; (width * height * channels) as usize]));
        let c = *c as usize;
        for row in 0..h.min(height.saturating_sub(y)) {
            let cols = w.min(width.saturating_sub(x)) as usize;
            let src = (row * w) as usize * c;
            let dst = ((y + row) * width + x) as usize * c;
            layer[dst..dst + cols * c].copy_from_slice(&data[src..src + cols * c]);
        }
    }

    /// Channel `k` of pixel (`x`, `y`) of `aov`.
    pub fn pixel(&self, aov: &str, x: u32, y: u32) -> &[f32] {
        let (c, data) = &self.layers[aov];
        let i = ((y * self.width + x) * c) as usize;
        &data[i..i + *c as usize]
    }
}

fn channel_names(aov: &str, channels: u32) -> Vec<String> {
    let base: &[&str] = match (aov, channels) {
        ("beauty", 4) => return ["R", "G", "B", "A"].map(String::from).to_vec(),
        ("normal" | "position", 3) => &["X", "Y", "Z"],
        ("depth", 1) => &["Z"],
        (_, 1) => &["Y"],
        _ => &["R", "G", "B", "A"],
    };
    base.iter().take(channels as usize).map(|c| format!("{aov}.{c}")).collect()
}

/// Writes every layer into one EXR part: beauty as `R G B A`, other AOVs as `aov.channel`
/// (`albedo.R`, `normal.X`, `depth.Z`), all 32-bit float, ZIP-compressed, with `metadata`
/// as string attributes in the header.
pub fn write_exr(path: &Path, image: &Image, metadata: &[(String, String)]) -> Result<()> {
    let n = (image.width * image.height) as usize;
    let mut channels: Vec<AnyChannel<FlatSamples>> = Vec::new();
    for (aov, (c, data)) in &image.layers {
        for (k, name) in channel_names(aov, *c).into_iter().enumerate() {
            let samples: Vec<f32> = (0..n).map(|i| data[i * *c as usize + k]).collect();
            channels.push(AnyChannel::new(name.as_str(), FlatSamples::F32(samples)));
        }
    }
    let mut attributes = LayerAttributes::named("");
    for (k, v) in metadata {
        let ascii: String = v.chars().map(|ch| if ch.is_ascii() { ch } else { '?' }).collect();
        if let (Some(key), Some(val)) = (Text::new_or_none(format!("tessera/{k}")), Text::new_or_none(ascii)) {
            attributes.other.insert(key, AttributeValue::Text(val));
        }
    }
    let layer =
        Layer::new((image.width as usize, image.height as usize), attributes, Encoding::SMALL_LOSSLESS, AnyChannels::sort(channels.into()));
    exr::image::Image::from_layer(layer).write().to_file(path).with_context(|| format!("cannot write {}", path.display()))?;
    Ok(())
}

/// A text attribute of a Tessera EXR's header (`key` without the `tessera/` prefix), read
/// without its pixels; `None` when the file, the header or the attribute is missing.
pub fn exr_attribute(path: &Path, key: &str) -> Option<String> {
    let meta = exr::meta::MetaData::read_from_file(path, false).ok()?;
    let value = meta.headers.first()?.own_attributes.other.get(&Text::new_or_none(format!("tessera/{key}"))?)?.clone();
    match value {
        AttributeValue::Text(t) => Some(t.to_string()),
        _ => None,
    }
}

/// The PNG preview path beside an EXR.
pub fn preview_path(exr: &Path) -> PathBuf {
    exr.with_extension("png")
}

/// Writes the beauty layer as an 8-bit sRGB PNG (clamped, no tone curve beyond sRGB).
pub fn write_png(path: &Path, image: &Image) -> Result<()> {
    let (c, data) = image.layers.get("beauty").context("no beauty layer to preview")?;
    let encode = |v: f32| -> u8 {
        let v = if v.is_finite() { v.clamp(0.0, 1.0) } else { 0.0 };
        let s = if v <= 0.003_130_8 { 12.92 * v } else { 1.055 * v.powf(1.0 / 2.4) - 0.055 };
        (s * 255.0 + 0.5) as u8
    };
    let rgb: Vec<u8> = data.chunks(*c as usize).flat_map(|p| [encode(p[0]), encode(p[1]), encode(p[2])]).collect();
    image::save_buffer(path, &rgb, image.width, image.height, image::ExtendedColorType::Rgb8)
        .with_context(|| format!("cannot write {}", path.display()))
}

/// Reads back an EXR written by [`write_exr`] (for tests and tools).
pub fn read_exr(path: &Path) -> Result<Image> {
    let img = read_all_flat_layers_from_file(path).with_context(|| format!("cannot read {}", path.display()))?;
    let layer = img.layer_data.first().context("EXR has no layers")?;
    let (w, h) = (layer.size.width() as u32, layer.size.height() as u32);
    let mut groups: BTreeMap<String, Vec<(String, Vec<f32>)>> = BTreeMap::new();
    for ch in &layer.channel_data.list {
        let name = ch.name.to_string();
        let (aov, chan) = match name.rsplit_once('.') {
            Some((a, c)) => (a.to_string(), c.to_string()),
            None => ("beauty".to_string(), name.clone()),
        };
        groups.entry(aov).or_default().push((chan, ch.sample_data.values_as_f32().collect()));
    }
    let order = ["R", "G", "B", "A", "X", "Y", "Z"];
    let mut out = Image { width: w, height: h, layers: BTreeMap::new() };
    for (aov, mut chans) in groups {
        chans.sort_by_key(|(c, _)| order.iter().position(|o| o == c).unwrap_or(99));
        let c = chans.len();
        let mut data = vec![0.0; w as usize * h as usize * c];
        for (k, (_, v)) in chans.iter().enumerate() {
            for (i, x) in v.iter().enumerate() {
                data[i * c + k] = *x;
            }
        }
        out.layers.insert(aov, (c as u32, data));
    }
    Ok(out)
}
