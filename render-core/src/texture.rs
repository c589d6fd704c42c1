//! Image textures: decoding, mip-map pyramids and filtered lookups.
//!
//! A [`Texture`] is built once per (file content, colour space) and shared by every material
//! that reads it. Eight-bit sources keep eight bits per channel in memory (a 16k × 16k RGBA
//! map is 1 GiB plus a third for its mips, not 4 GiB of floats); sRGB-encoded ones are
//! linearised through a table at lookup, after their mips were averaged in linear light.
//! Everything else is stored as half floats.
//!
//! Coordinates follow USD: `st` (0, 0) is the image's bottom-left corner, (1, 1) its top-right
//! (UsdPreviewSurface specification, "Texture Coordinate Orientation in USD").

use glam::{Vec2, Vec4};
use half::f16;

/// How a lookup outside [0, 1] wraps (UsdUVTexture `wrapS` / `wrapT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Wrap {
    /// Tile the image.
    #[default]
    Repeat,
    /// Tile, flipping every other copy.
    Mirror,
    /// Extend the edge texels.
    Clamp,
    /// Zero outside the image.
    Black,
}

impl Wrap {
    /// The mode a UsdUVTexture token names. `useMetadata` reads wrap metadata from the file,
    /// which none of our decoders expose; it falls back to `repeat`, as glTF-derived assets
    /// (the usual authors of the token) expect. Unknown tokens give `None`.
    pub fn from_token(token: &str) -> Option<Wrap> {
        Some(match token {
            "repeat" | "useMetadata" => Wrap::Repeat,
            "mirror" => Wrap::Mirror,
            "clamp" => Wrap::Clamp,
            "black" => Wrap::Black,
            _ => return None,
        })
    }

    /// The texel index for integer coordinate `i` in an axis of `n` texels, or `None` when the
    /// lookup is black.
    #[inline]
    pub(crate) fn index(self, i: i64, n: usize) -> Option<usize> {
        if (0..n as i64).contains(&i) {
            // Inside the image every mode reads the texel itself; the modes below divide.
            return Some(i as usize);
        }
        let n = n as i64;
        Some(match self {
            Wrap::Repeat => i.rem_euclid(n),
            Wrap::Mirror => {
                let period = i.rem_euclid(2 * n);
                if period < n { period } else { 2 * n - 1 - period }
            }
            Wrap::Clamp => i.clamp(0, n - 1),
            Wrap::Black => {
                if (0..n).contains(&i) {
                    i
                } else {
                    return None;
                }
            }
        } as usize)
    }
}

/// How a texture's values are encoded (UsdUVTexture `sourceColorSpace`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, Default)]
pub enum ColorSpace {
    /// sRGB for integer-coded (8- or 16-bit) images of three or more channels, linear
    /// otherwise: a single-channel image is data (roughness, masks), a colour picture is sRGB
    /// whatever its bit depth, and float images (EXR, HDR) are linear. This is MoonRay's rule
    /// ("gamma if not single channel"), and what usdrecord 24.03 shows for the USD-WG
    /// TextureFileFormatTests (8- and 16-bit PNGs alike).
    #[default]
    Auto,
    /// Linear values.
    Raw,
    /// The sRGB transfer function.
    Srgb,
}

impl ColorSpace {
    /// The colour space a token names, or `None` for unknown tokens.
    pub fn from_token(token: &str) -> Option<ColorSpace> {
        Some(match token {
            "auto" => ColorSpace::Auto,
            "raw" => ColorSpace::Raw,
            "sRGB" => ColorSpace::Srgb,
            _ => return None,
        })
    }
}

/// Why an image could not become a texture.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// The bytes are not an image any decoder reads.
    #[error("cannot decode '{name}': {reason}")]
    Decode {
        /// The file name, for the message.
        name: String,
        /// The decoder's explanation.
        reason: String,
    },
    /// Decoding the image would need more memory than the budget has free.
    #[error("'{name}' is {width}×{height}: decoding it needs {bytes} bytes, over the {budget} the memory budget has free")]
    OverBudget {
        /// The file name.
        name: String,
        /// Width in texels.
        width: u32,
        /// Height in texels.
        height: u32,
        /// Peak bytes decoding would hold.
        bytes: u64,
        /// Bytes free.
        budget: u64,
    },
    /// The image is larger than the limit.
    #[error("'{name}' is {width}×{height}, above the limit of {limit} texels per side (or of the server's texel budget)")]
    TooLarge {
        /// The file name.
        name: String,
        /// Width in texels.
        width: u32,
        /// Height in texels.
        height: u32,
        /// The limit.
        limit: u32,
    },
}

/// A texture file named by content: what a material input or a dome light holds.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct TextureRef {
    /// `sha256:` and 64 hex digits.
    pub hash: String,
    /// The authored path, for messages.
    pub source: String,
}

/// The largest side accepted: 16k textures are the largest common production maps.
pub const MAX_TEXTURE_SIDE: u32 = 16384;

/// A decoded image before a colour space makes it a [`Texture`].
#[derive(Clone, Debug)]
pub struct Image {
    width: u32,
    height: u32,
    channels: usize,
    texels: Texels,
    /// The file stored integer codes (8 or 16 bits), which may be sRGB-encoded.
    integer_coded: bool,
    /// The file says its values are sRGB-encoded (an OpenEXR `colorInteropID` of `srgb_*`).
    declared_srgb: bool,
}

#[derive(Clone, Debug)]
enum Texels {
    U8(Vec<u8>),
    F16(Vec<f16>),
}

impl Texels {
    fn len(&self) -> usize {
        match self {
            Texels::U8(v) => v.len(),
            Texels::F16(v) => 2 * v.len(),
        }
    }
}

/// A decoded image's texels as stored: 8-bit as they are, deeper ones as half floats (16-bit
/// codes scaled to [0, 1]), each converted in one pass without a float copy between.
fn texels_of(img: image::DynamicImage) -> (usize, Texels) {
    use image::DynamicImage as D;
    let half = |v: &[f32]| v.iter().map(|&x| f16::from_f32(if x.is_finite() { x } else { 0.0 })).collect();
    let unorm16 = |v: &[u16]| v.iter().map(|&x| f16::from_f32(f32::from(x) / 65535.0)).collect();
    match img {
        D::ImageLuma8(b) => (1, Texels::U8(b.into_raw())),
        D::ImageLumaA8(b) => (2, Texels::U8(b.into_raw())),
        D::ImageRgb8(b) => (3, Texels::U8(b.into_raw())),
        D::ImageRgba8(b) => (4, Texels::U8(b.into_raw())),
        D::ImageLuma16(b) => (1, Texels::F16(unorm16(b.as_raw()))),
        D::ImageLumaA16(b) => (2, Texels::F16(unorm16(b.as_raw()))),
        D::ImageRgb16(b) => (3, Texels::F16(unorm16(b.as_raw()))),
        D::ImageRgba16(b) => (4, Texels::F16(unorm16(b.as_raw()))),
        D::ImageRgb32F(b) => (3, Texels::F16(half(b.as_raw()))),
        D::ImageRgba32F(b) => (4, Texels::F16(half(b.as_raw()))),
        other => (4, Texels::F16(half(other.to_rgba32f().as_raw()))),
    }
}

impl Image {
    /// Decodes PNG, JPEG, OpenEXR, Radiance HDR, TIFF or TGA bytes; `name` is used in errors.
    pub fn decode(bytes: &[u8], name: &str) -> Result<Image, TextureError> {
        Self::decode_within(bytes, name, u64::from(MAX_TEXTURE_SIDE) * u64::from(MAX_TEXTURE_SIDE), u64::MAX)
    }

    /// [`Self::decode`], refusing before decoding an image of more than `max_texels` texels or
    /// whose decoding would hold more than `max_bytes` at its peak (the decoder's own buffer
    /// and the converted texels together): a few bytes of header can claim gigabytes. A
    /// decoder failure of any kind, a panic included, is an error.
    pub fn decode_within(bytes: &[u8], name: &str, max_texels: u64, max_bytes: u64) -> Result<Image, TextureError> {
        use image::{DynamicImage as D, ImageDecoder};
        let err = |reason: String| TextureError::Decode { name: name.to_string(), reason };
        // Formats without a signature (TGA) are known by the file's extension.
        let open = || -> Result<_, TextureError> {
            let mut reader = image::ImageReader::new(std::io::Cursor::new(bytes)).with_guessed_format().map_err(|e| err(e.to_string()))?;
            if reader.format().is_none()
                && let Ok(f) = image::ImageFormat::from_path(name)
            {
                reader.set_format(f);
            }
            let mut limits = image::Limits::default();
            limits.max_alloc = Some(max_bytes);
            reader.limits(limits);
            Ok(reader)
        };
        let decoder = open()?.into_decoder().map_err(|e| err(e.to_string()))?;
        let (w, h) = decoder.dimensions();
        if w > MAX_TEXTURE_SIDE || h > MAX_TEXTURE_SIDE || u64::from(w) * u64::from(h) > max_texels {
            return Err(TextureError::TooLarge { name: name.to_string(), width: w, height: h, limit: MAX_TEXTURE_SIDE });
        }
        let color = decoder.color_type();
        let (channels, depth) = (u64::from(color.channel_count()), u64::from(color.bytes_per_pixel()) / u64::from(color.channel_count()));
        // 8-bit texels are kept as decoded; deeper ones are converted to half floats beside them.
        let peak = decoder.total_bytes().saturating_add(if depth == 1 { 0 } else { u64::from(w) * u64::from(h) * channels * 2 });
        if peak > max_bytes {
            return Err(TextureError::OverBudget { name: name.to_string(), width: w, height: h, bytes: peak, budget: max_bytes });
        }
        drop(decoder);
        let reader = open()?;
        let exr = reader.format() == Some(image::ImageFormat::OpenExr);
        let img = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| reader.decode()))
            .map_err(|_| err("the decoder failed (panicked)".into()))?
            .map_err(|e| err(e.to_string()))?;
        let (width, height) = (img.width(), img.height());
        if width == 0 || height == 0 {
            return Err(err("the image is empty".into()));
        }
        let integer_coded = !matches!(img, D::ImageRgb32F(_) | D::ImageRgba32F(_));
        let declared_srgb = exr && exr_declares_srgb(bytes);
        let (channels, texels) = texels_of(img);
        Ok(Image { width, height, channels, texels, integer_coded, declared_srgb })
    }

    /// An image from linear float texels, row-major from the top row, `channels` per texel.
    /// NaN and infinite texels read as 0, as decoded files' do.
    pub fn from_f32(width: u32, height: u32, channels: usize, texels: &[f32]) -> Image {
        assert!((1..=4).contains(&channels) && texels.len() == width as usize * height as usize * channels);
        let texels = texels.iter().map(|&x| f16::from_f32(if x.is_finite() { x } else { 0.0 })).collect();
        Image { width, height, channels, texels: Texels::F16(texels), integer_coded: false, declared_srgb: false }
    }

    /// An image from 8-bit texels, row-major from the top row.
    pub fn from_u8(width: u32, height: u32, channels: usize, texels: Vec<u8>) -> Image {
        assert!((1..=4).contains(&channels) && texels.len() == width as usize * height as usize * channels);
        Image { width, height, channels, texels: Texels::U8(texels), integer_coded: true, declared_srgb: false }
    }

    /// Width and height in texels.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Channels per texel (1 to 4).
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.texels.len()
    }

    /// True when `space` means sRGB for this image.
    fn is_srgb(&self, space: ColorSpace) -> bool {
        match space {
            ColorSpace::Raw => false,
            ColorSpace::Srgb => true,
            ColorSpace::Auto => (self.integer_coded || self.declared_srgb) && self.channels >= 3,
        }
    }
}

/// True when an OpenEXR file's header says its values are sRGB-encoded: a `colorInteropID`
/// (the ASWF Color Interop Forum's identifiers, OpenEXR 3.3) beginning `srgb_`. Blender 5
/// saves float images it holds in sRGB this way (`srgb_rec709_display`), values above 1
/// included (the curve extended), and reads them back through the curve; read as linear, such
/// a map is several times too bright in its shadows. Unreadable headers say nothing.
fn exr_declares_srgb(bytes: &[u8]) -> bool {
    let Ok(meta) = exr::meta::MetaData::read_from_buffered(std::io::Cursor::new(bytes), false) else { return false };
    let key = exr::meta::attribute::Text::from("colorInteropID");
    meta.headers.first().is_some_and(|h| {
        [h.own_attributes.other.get(&key), h.shared_attributes.other.get(&key)]
            .into_iter()
            .flatten()
            .any(|v| matches!(v, exr::meta::attribute::AttributeValue::Text(t) if t.to_string().starts_with("srgb_")))
    })
}

/// sRGB electro-optical transfer function (IEC 61966-2-1).
#[inline]
pub fn srgb_to_linear(x: f32) -> f32 {
    if x <= 0.04045 { x / 12.92 } else { ((x + 0.055) / 1.055).powf(2.4) }
}

/// Inverse of [`srgb_to_linear`].
#[inline]
pub fn linear_to_srgb(x: f32) -> f32 {
    if x <= 0.0031308 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 }
}

fn srgb_table() -> &'static [f32; 256] {
    static TABLE: std::sync::OnceLock<[f32; 256]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| std::array::from_fn(|i| srgb_to_linear(i as f32 / 255.0)))
}

/// One level of the pyramid.
#[derive(Clone, Debug)]
struct Level {
    width: usize,
    height: usize,
    texels: Texels,
}

/// A filtered, mip-mapped texture.
#[derive(Clone, Debug)]
pub struct Texture {
    levels: Vec<Level>,
    channels: usize,
    /// 8-bit texels hold sRGB codes (decoded through a table at lookup).
    srgb: bool,
}

impl Texture {
    /// Builds the pyramid of `image` read in colour space `space`. Each level halves the
    /// previous one (rounding up) by averaging 2 × 2 texels in linear light, so a texture
    /// seen from far away keeps its mean colour.
    pub fn new(image: &Image, space: ColorSpace) -> Texture {
        let srgb = image.is_srgb(space);
        // Half-float texels are linearised once here; 8-bit ones through a table at lookup.
        let base =
            match &image.texels {
                Texels::F16(v) if srgb => Texels::F16(
                    v.iter()
                        .enumerate()
                        .map(|(i, x)| {
                            if is_colour_channel(i % image.channels, image.channels) {
                                f16::from_f32(srgb_to_linear(x.to_f32()))
                            } else {
                                *x
                            }
                        })
                        .collect(),
                ),
                other => other.clone(),
            };
        let srgb = srgb && matches!(base, Texels::U8(_));
        let mut levels = vec![Level { width: image.width as usize, height: image.height as usize, texels: base }];
        let c = image.channels;
        while let Some(last) = levels.last().filter(|l| l.width > 1 || l.height > 1) {
            let (w, h) = (last.width.div_ceil(2), last.height.div_ceil(2));
            let mut sum = vec![0.0f32; w * h * c];
            for y in 0..h {
                for x in 0..w {
                    let mut n = 0.0;
                    for (sx, sy) in [(2 * x, 2 * y), (2 * x + 1, 2 * y), (2 * x, 2 * y + 1), (2 * x + 1, 2 * y + 1)] {
                        if sx < last.width && sy < last.height {
                            n += 1.0;
                            for k in 0..c {
                                sum[(y * w + x) * c + k] += texel_linear(&last.texels, (sy * last.width + sx) * c + k, srgb, k, c);
                            }
                        }
                    }
                    sum[(y * w + x) * c..(y * w + x + 1) * c].iter_mut().for_each(|v| *v /= n);
                }
            }
            let texels = match &last.texels {
                Texels::U8(_) => Texels::U8(
                    sum.iter()
                        .enumerate()
                        .map(|(i, &v)| {
                            let encoded = if srgb && is_colour_channel(i % c, c) { linear_to_srgb(v) } else { v };
                            (encoded * 255.0).round().clamp(0.0, 255.0) as u8
                        })
                        .collect(),
                ),
                Texels::F16(_) => Texels::F16(sum.iter().map(|&v| f16::from_f32(v)).collect()),
            };
            levels.push(Level { width: w, height: h, texels });
        }
        Texture { levels, channels: c, srgb }
    }

    /// Width and height of the finest level.
    pub fn size(&self) -> (usize, usize) {
        (self.levels[0].width, self.levels[0].height)
    }

    /// Number of mip levels.
    pub fn level_count(&self) -> usize {
        self.levels.len()
    }

    /// Bytes held by all levels.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(|l| l.texels.len()).sum()
    }

    /// Channels per texel.
    pub fn channels(&self) -> usize {
        self.channels
    }

    /// The filtered value at `st` for a footprint `lod` levels above the finest (trilinear:
    /// bilinear in the two nearest levels, blended). Channels missing from the image read as
    /// UsdUVTexture does: grey images give r = g = b, and alpha is 1 when absent.
    pub fn lookup(&self, st: Vec2, lod: f32, wrap: [Wrap; 2]) -> Vec4 {
        if !st.is_finite() {
            return Vec4::new(0.0, 0.0, 0.0, 1.0);
        }
        let max = (self.levels.len() - 1) as f32;
        let lod = if lod.is_nan() { 0.0 } else { lod.clamp(0.0, max) };
        let lo = lod.floor() as usize;
        let t = lod - lo as f32;
        let a = self.bilinear(lo, st, wrap);
        let v = if t > 0.0 && lo + 1 < self.levels.len() { a.lerp(self.bilinear(lo + 1, st, wrap), t) } else { a };
        self.expand(v)
    }

    /// The value of texel (`x`, `y`) of the finest level, `y` counted from the top row.
    pub fn texel(&self, x: usize, y: usize) -> Vec4 {
        self.expand(self.fetch(0, x, y))
    }

    fn expand(&self, v: Vec4) -> Vec4 {
        match self.channels {
            1 => Vec4::new(v.x, v.x, v.x, 1.0),
            2 => Vec4::new(v.x, v.x, v.x, v.y),
            3 => v.truncate().extend(1.0),
            _ => v,
        }
    }

    fn fetch(&self, level: usize, x: usize, y: usize) -> Vec4 {
        let l = &self.levels[level];
        let (c, base) = (self.channels, (y * l.width + x) * self.channels);
        let mut v = Vec4::ZERO;
        // The storage is matched once a texel, not once a channel.
        match &l.texels {
            Texels::U8(t) => {
                for (k, &byte) in t[base..base + c].iter().enumerate() {
                    v[k] = byte_linear(byte, self.srgb && is_colour_channel(k, c));
                }
            }
            Texels::F16(t) => {
                for (k, half) in t[base..base + c].iter().enumerate() {
                    v[k] = half.to_f32();
                }
            }
        }
        v
    }

    fn bilinear(&self, level: usize, st: Vec2, wrap: [Wrap; 2]) -> Vec4 {
        let l = &self.levels[level];
        // Texel centres sit at half-integers; t runs bottom to top, rows top to bottom.
        let x = st.x as f64 * l.width as f64 - 0.5;
        let y = (1.0 - st.y as f64) * l.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        // Each axis's two texel indices, wrapped once rather than once per corner.
        let xs = [wrap[0].index(x0, l.width), wrap[0].index(x0 + 1, l.width)];
        let ys = [wrap[1].index(y0, l.height), wrap[1].index(y0 + 1, l.height)];
        let mut v = Vec4::ZERO;
        for (dx, dy, w) in [(0, 0, (1.0 - fx) * (1.0 - fy)), (1, 0, fx * (1.0 - fy)), (0, 1, (1.0 - fx) * fy), (1, 1, fx * fy)] {
            if w == 0.0 {
                continue;
            }
            if let (Some(ix), Some(iy)) = (xs[dx], ys[dy]) {
                v += w * self.fetch(level, ix, iy);
            }
        }
        v
    }
}

/// Alpha (the last channel of a 2- or 4-channel image) is never sRGB-encoded.
#[inline]
fn is_colour_channel(k: usize, channels: usize) -> bool {
    !((channels == 2 && k == 1) || (channels == 4 && k == 3))
}

#[inline]
fn texel_linear(texels: &Texels, i: usize, srgb: bool, k: usize, channels: usize) -> f32 {
    match texels {
        Texels::U8(v) => byte_linear(v[i], srgb && is_colour_channel(k, channels)),
        Texels::F16(v) => v[i].to_f32(),
    }
}

/// An 8-bit channel's linear value, decoded from sRGB when `srgb`.
#[inline]
fn byte_linear(byte: u8, srgb: bool) -> f32 {
    if srgb { srgb_table()[byte as usize] } else { byte as f32 / 255.0 }
}

/// The mip level for a lookup by ray cones (Akenine-Möller et al., "Texture Level of Detail
/// Strategies for Real-Time Ray Tracing", Ray Tracing Gems, 2019, chapter 20): a cone of
/// world-space `width` meeting a surface at cosine `cos_theta`, on a triangle whose texture
/// area per world area is `uv_density`² (in st units), over a texture `size` texels big.
pub fn ray_cone_lod(width: f32, cos_theta: f32, uv_density: f32, size: (usize, usize)) -> f32 {
    let texels = texels_a_side(size);
    // Grazing footprints stretch without bound; 1/64 caps the blur at six levels.
    let footprint = width * uv_density * texels / cos_theta.abs().max(1.0 / 64.0);
    if footprint > 0.0 && footprint.is_finite() { footprint.log2().max(0.0) } else { 0.0 }
}

/// Texels along a side of a texture of `size`, the geometric mean of its width and height.
pub fn texels_a_side(size: (usize, usize)) -> f32 {
    (size.0 as f32 * size.1 as f32).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 2 × 2 image: red top-left, green top-right, blue bottom-left, white bottom-right.
    fn quadrants() -> Image {
        Image::from_f32(2, 2, 3, &[1., 0., 0., 0., 1., 0., 0., 0., 1., 1., 1., 1.])
    }

    #[test]
    fn st_origin_is_the_bottom_left_of_the_image() {
        let t = Texture::new(&quadrants(), ColorSpace::Raw);
        let at = |s: f32, tt: f32| t.lookup(Vec2::new(s, tt), 0.0, [Wrap::Clamp; 2]).truncate();
        assert_eq!(at(0.25, 0.25), glam::Vec3::Z, "bottom-left is blue");
        assert_eq!(at(0.25, 0.75), glam::Vec3::X, "top-left is red");
        assert_eq!(at(0.75, 0.75), glam::Vec3::Y, "top-right is green");
        assert_eq!(at(0.75, 0.25), glam::Vec3::ONE);
    }

    #[test]
    fn wrap_modes_extend_the_image_as_the_specification_says() {
        let t = Texture::new(&quadrants(), ColorSpace::Raw);
        let at = |s: f32, w: Wrap| t.lookup(Vec2::new(s, 0.75), 0.0, [w, Wrap::Clamp]).truncate();
        // Just right of the image: repeat wraps to its left column (red), mirror and clamp
        // stay on the right column (green), black is zero.
        assert_eq!(at(1.25, Wrap::Repeat), glam::Vec3::X);
        assert_eq!(at(1.25, Wrap::Mirror), glam::Vec3::Y);
        assert_eq!(at(1.75, Wrap::Mirror), glam::Vec3::X);
        assert_eq!(at(1.75, Wrap::Clamp), glam::Vec3::Y);
        assert_eq!(at(1.25, Wrap::Black), glam::Vec3::ZERO);
        assert_eq!(at(-0.25, Wrap::Repeat), glam::Vec3::Y);
    }

    #[test]
    fn every_mip_level_keeps_the_mean_in_linear_light() {
        // An 8-bit sRGB checker of black and white averages to linear 0.5, not to sRGB code 128
        // (linear 0.216), which a naive average of codes would give.
        let (w, h) = (16, 12);
        let texels: Vec<u8> = (0..w * h).flat_map(|i| if (i % w + i / w) % 2 == 0 { [255u8; 3] } else { [0u8; 3] }).collect();
        let t = Texture::new(&Image::from_u8(w as u32, h as u32, 3, texels), ColorSpace::Srgb);
        assert_eq!(t.level_count(), 5, "16×12 → 8×6 → 4×3 → 2×2 → 1×1");
        let top = t.lookup(Vec2::splat(0.5), 100.0, [Wrap::Repeat; 2]);
        assert!((top.x - 0.5).abs() < 0.01, "coarsest level {top}");
        assert_eq!(top.w, 1.0);
    }

    #[test]
    fn auto_colour_space_is_srgb_only_for_8_bit_colour() {
        let grey = Image::from_u8(1, 1, 1, vec![128]);
        let rgb = Image::from_u8(1, 1, 3, vec![128; 3]);
        let float = Image::from_f32(1, 1, 3, &[0.5; 3]);
        let v = |i: &Image, s| Texture::new(i, s).texel(0, 0).x;
        assert!((v(&grey, ColorSpace::Auto) - 128.0 / 255.0).abs() < 1e-6);
        assert!((v(&rgb, ColorSpace::Auto) - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
        assert!((v(&rgb, ColorSpace::Raw) - 128.0 / 255.0).abs() < 1e-6);
        assert!((v(&float, ColorSpace::Auto) - 0.5).abs() < 1e-3);
        assert!((v(&float, ColorSpace::Srgb) - srgb_to_linear(0.5)).abs() < 1e-3, "explicit sRGB applies to floats too");
        assert!((v(&grey, ColorSpace::Srgb) - srgb_to_linear(128.0 / 255.0)).abs() < 1e-6);
    }

    /// A 2 × 1 RGB OpenEXR of `values` (32-bit float), with a `colorInteropID` when given.
    fn exr_of(values: [f32; 2], interop: Option<&str>) -> Vec<u8> {
        use exr::prelude::*;
        let mut layer = Layer::new(
            (2, 1),
            LayerAttributes::named("rgb"),
            Encoding::UNCOMPRESSED,
            SpecificChannels::rgb(|p: Vec2<usize>| (values[p.0], values[p.0], values[p.0])),
        );
        if let Some(id) = interop {
            layer.attributes.other.insert(Text::from("colorInteropID"), AttributeValue::Text(Text::from(id)));
        }
        let mut bytes = Vec::new();
        Image::from_layer(layer).write().to_buffered(std::io::Cursor::new(&mut bytes)).unwrap();
        bytes
    }

    /// Blender 5 saves a float image it holds in sRGB as an OpenEXR of sRGB-coded values marked
    /// `srgb_rec709_display` (linear 0.06 written as 0.2717, 40 as 4.65 on the extended
    /// curve). Read with `auto`, such a file decodes through the curve; an unmarked or linear
    /// one does not; an explicit `raw` wins.
    #[test]
    fn exr_files_marked_srgb_decode_through_the_curve() {
        let coded = [linear_to_srgb(0.06), 1.055 * 40f32.powf(1.0 / 2.4) - 0.055];
        let read = |interop, space| {
            let t = Texture::new(&Image::decode(&exr_of(coded, interop), "t.exr").unwrap(), space);
            [t.texel(0, 0).x, t.texel(1, 0).x]
        };
        let [dark, bright] = read(Some("srgb_rec709_display"), ColorSpace::Auto);
        // Half-float texels: about three significant digits.
        assert!((dark - 0.06).abs() < 2e-4 && (bright - 40.0).abs() < 0.05, "{dark} {bright}");
        for (interop, space) in
            [(None, ColorSpace::Auto), (Some("lin_rec709_scene"), ColorSpace::Auto), (Some("srgb_rec709_display"), ColorSpace::Raw)]
        {
            let [dark, _] = read(interop, space);
            assert!((dark - coded[0]).abs() < 2e-4, "{interop:?} {space:?}: {dark}");
        }
    }

    #[test]
    fn srgb_round_trips() {
        for i in 0..=100 {
            let x = i as f32 / 100.0;
            assert!((linear_to_srgb(srgb_to_linear(x)) - x).abs() < 1e-5);
        }
    }

    #[test]
    fn grey_and_alpha_expand_as_usd_reads_them() {
        let la = Texture::new(&Image::from_f32(1, 1, 2, &[0.25, 0.5]), ColorSpace::Raw);
        assert_eq!(la.texel(0, 0), Vec4::new(0.25, 0.25, 0.25, 0.5));
    }

    #[test]
    fn ray_cone_lod_grows_with_distance_and_grazing() {
        let size = (1024, 1024);
        // A footprint of one texel is level 0; doubling it is one level up.
        assert!(ray_cone_lod(1.0 / 1024.0, 1.0, 1.0, size).abs() < 1e-4);
        assert!((ray_cone_lod(2.0 / 1024.0, 1.0, 1.0, size) - 1.0).abs() < 1e-4);
        assert!((ray_cone_lod(1.0 / 1024.0, 0.5, 1.0, size) - 1.0).abs() < 1e-4);
        assert_eq!(ray_cone_lod(0.0, 0.0, 1.0, size), 0.0);
        assert!(ray_cone_lod(f32::NAN, 1.0, 1.0, size) == 0.0);
    }

    #[test]
    fn nan_and_infinite_texels_read_as_zero_at_every_level() {
        // Hard case (issue 7): a NaN texel must not poison lookups, mips or the dome's sums.
        let t = Texture::new(&Image::from_f32(2, 2, 1, &[f32::NAN, 1.0, f32::INFINITY, 1.0]), ColorSpace::Raw);
        assert_eq!(t.texel(0, 0).x, 0.0);
        assert_eq!(t.texel(0, 1).x, 0.0);
        for lod in [0.0, 0.5, 1.0, 30.0] {
            let v = t.lookup(Vec2::new(0.3, 0.6), lod, [Wrap::Repeat; 2]);
            assert!(v.is_finite(), "lod {lod}: {v}");
        }
        assert!((t.lookup(Vec2::splat(0.5), 10.0, [Wrap::Repeat; 2]).x - 0.5).abs() < 1e-3);
        // Non-finite coordinates and levels give finite values too.
        assert!(t.lookup(Vec2::new(f32::NAN, 0.5), 0.0, [Wrap::Repeat; 2]).is_finite());
        assert!(t.lookup(Vec2::new(1e30, -1e30), f32::NAN, [Wrap::Mirror; 2]).is_finite());
    }

    #[test]
    fn a_one_texel_texture_is_that_texel_everywhere() {
        let t = Texture::new(&Image::from_u8(1, 1, 3, vec![255, 128, 0]), ColorSpace::Raw);
        assert_eq!(t.level_count(), 1);
        for st in [Vec2::ZERO, Vec2::splat(0.5), Vec2::new(7.3, -2.2)] {
            for wrap in [Wrap::Repeat, Wrap::Mirror, Wrap::Clamp] {
                for lod in [0.0, 3.0] {
                    let v = t.lookup(st, lod, [wrap; 2]);
                    assert!((v - Vec4::new(1.0, 128.0 / 255.0, 0.0, 1.0)).abs().max_element() < 1e-6, "{st} {wrap:?}: {v}");
                }
            }
        }
        // Black wrap outside [0, 1]: half the bilinear footprint falls outside at the edge.
        assert_eq!(t.lookup(Vec2::new(2.5, 0.5), 0.0, [Wrap::Black, Wrap::Clamp]).truncate(), glam::Vec3::ZERO);
    }

    #[test]
    fn decode_reports_the_file_name() {
        let e = Image::decode(b"not an image", "wood.png").unwrap_err();
        assert!(e.to_string().contains("wood.png"), "{e}");
        let mut png = Vec::new();
        image::RgbImage::from_pixel(3, 2, image::Rgb([10, 20, 30]))
            .write_to(&mut std::io::Cursor::new(&mut png), image::ImageFormat::Png)
            .unwrap();
        let i = Image::decode(&png, "a.png").unwrap();
        assert_eq!((i.size(), i.channels()), ((3, 2), 3));
        // A header claiming more texels than the budget is refused before decoding.
        let e = Image::decode_within(&png, "a.png", 5, u64::MAX).unwrap_err();
        assert!(matches!(e, TextureError::TooLarge { width: 3, height: 2, .. }), "{e}");
    }
}
