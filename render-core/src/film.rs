//! The film: per-pixel sums of every AOV in f64 (as pbrt-v4's `RGBFilm` does), kept per
//! tile so each tile is owned by one worker at a time. The main sums take 11 f64 per pixel;
//! position and the light-path components (with their direct parts) 30 more, allocated only
//! when a render asks for one of them (240 B per pixel: 500 MB at 1920x1080).

use glam::Vec3;

use crate::math::luminance;

/// Arbitrary output variables the film records.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum Aov {
    /// Radiance (RGB) and coverage (A).
    Beauty,
    /// Reflectance of the first surface.
    Albedo,
    /// World-space shading normal of the first surface, facing the camera.
    Normal,
    /// Camera-space depth of the first surface.
    Depth,
    /// World-space position of the first surface.
    Position,
    /// Light that left the first surface through a diffuse lobe (Lambert, Disney diffuse,
    /// sheen), directly or after further bounces.
    Diffuse,
    /// Light reflected by the first surface's glossy and mirror lobes (microfacet reflection,
    /// clearcoat, a dielectric's reflection).
    Specular,
    /// Light transmitted through the first surface (a dielectric's refraction, diffuse
    /// transmission).
    Transmission,
    /// Light the camera sees directly: emitters and the environment.
    Emission,
    /// Light that entered the first surface's subsurface medium and left it after a random
    /// walk inside, directly or after further bounces (what a transmission into a medium
    /// becomes; light only refracted through a boundary stays `Transmission`).
    Subsurface,
    /// The part of `Diffuse` that came straight from an emitter to the first surface (next-event
    /// estimation there, or the first bounce's ray meeting an emitter).
    DiffuseDirect,
    /// The part of `Specular` straight from an emitter.
    SpecularDirect,
    /// The part of `Transmission` straight from an emitter.
    TransmissionDirect,
    /// The part of `Subsurface` that reached the medium straight from an emitter: lighting at
    /// its scattering events and at the walk's exit, before the path meets another surface.
    SubsurfaceDirect,
    /// `Diffuse` minus `DiffuseDirect`: light that met at least one more surface.
    DiffuseIndirect,
    /// `Specular` minus `SpecularDirect`.
    SpecularIndirect,
    /// `Transmission` minus `TransmissionDirect`.
    TransmissionIndirect,
    /// `Subsurface` minus `SubsurfaceDirect`.
    SubsurfaceIndirect,
    /// Camera samples the pixel received (fewer than asked where adaptive sampling stopped).
    SampleCount,
    /// Estimated variance of the pixel's mean luminance (the square of its standard error).
    Variance,
    /// Which prim the pixel's first camera sample saw: 0 for none, else 1 + its index in the
    /// render's prim table (`Started.prim_paths`; the EXR header `primIdPaths`). Not averaged:
    /// ids are labels.
    PrimId,
}

impl Aov {
    /// All AOVs.
    pub const ALL: [Aov; 21] = [
        Aov::Beauty,
        Aov::Albedo,
        Aov::Normal,
        Aov::Depth,
        Aov::Position,
        Aov::Diffuse,
        Aov::Specular,
        Aov::Transmission,
        Aov::Subsurface,
        Aov::Emission,
        Aov::DiffuseDirect,
        Aov::SpecularDirect,
        Aov::TransmissionDirect,
        Aov::SubsurfaceDirect,
        Aov::DiffuseIndirect,
        Aov::SpecularIndirect,
        Aov::TransmissionIndirect,
        Aov::SubsurfaceIndirect,
        Aov::SampleCount,
        Aov::Variance,
        Aov::PrimId,
    ];

    /// The light-path components: their sum is the beauty's RGB.
    pub const COMPONENTS: [Aov; 5] = [Aov::Diffuse, Aov::Specular, Aov::Transmission, Aov::Emission, Aov::Subsurface];

    /// The AOV's wire and file name.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Beauty => "beauty",
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
            Aov::Position => "position",
            Aov::Diffuse => "diffuse",
            Aov::Specular => "specular",
            Aov::Transmission => "transmission",
            Aov::Emission => "emission",
            Aov::Subsurface => "subsurface",
            Aov::DiffuseDirect => "diffuse_direct",
            Aov::SpecularDirect => "specular_direct",
            Aov::TransmissionDirect => "transmission_direct",
            Aov::SubsurfaceDirect => "subsurface_direct",
            Aov::DiffuseIndirect => "diffuse_indirect",
            Aov::SpecularIndirect => "specular_indirect",
            Aov::TransmissionIndirect => "transmission_indirect",
            Aov::SubsurfaceIndirect => "subsurface_indirect",
            Aov::SampleCount => "sampleCount",
            Aov::Variance => "variance",
            Aov::PrimId => "primId",
        }
    }

    /// True for the AOVs kept in a tile's optional second buffer (so renders that do not ask
    /// for them do not pay their memory).
    pub fn is_extra(self) -> bool {
        !self.is_statistic() && self.offset() >= VALUES
    }

    /// True for the AOVs computed from the sample statistics rather than accumulated.
    pub fn is_statistic(self) -> bool {
        matches!(self, Aov::SampleCount | Aov::Variance | Aov::PrimId)
    }

    /// For an indirect part, the total and the direct part it is the difference of.
    pub fn indirect_parts(self) -> Option<(Aov, Aov)> {
        match self {
            Aov::DiffuseIndirect => Some((Aov::Diffuse, Aov::DiffuseDirect)),
            Aov::SpecularIndirect => Some((Aov::Specular, Aov::SpecularDirect)),
            Aov::TransmissionIndirect => Some((Aov::Transmission, Aov::TransmissionDirect)),
            Aov::SubsurfaceIndirect => Some((Aov::Subsurface, Aov::SubsurfaceDirect)),
            _ => None,
        }
    }

    /// Parses a wire name.
    pub fn from_name(name: &str) -> Option<Aov> {
        Aov::ALL.into_iter().find(|a| a.name() == name)
    }

    /// Channels per pixel.
    pub fn channels(self) -> usize {
        match self {
            Aov::Beauty => 4,
            Aov::Depth | Aov::SampleCount | Aov::Variance | Aov::PrimId => 1,
            _ => 3,
        }
    }

    /// Where the AOV's values start: below [`VALUES`] in the main sums, above in the extra.
    fn offset(self) -> usize {
        match self {
            Aov::Beauty => 0,
            Aov::Albedo => 4,
            Aov::Normal => 7,
            Aov::Depth => 10,
            Aov::Position => VALUES,
            Aov::Diffuse => VALUES + 3,
            Aov::Specular => VALUES + 6,
            Aov::Transmission => VALUES + 9,
            Aov::Emission => VALUES + 12,
            Aov::Subsurface => VALUES + 15,
            Aov::DiffuseDirect => VALUES + 18,
            Aov::SpecularDirect => VALUES + 21,
            Aov::TransmissionDirect => VALUES + 24,
            Aov::SubsurfaceDirect => VALUES + 27,
            // Resolved as the total minus the direct part.
            Aov::DiffuseIndirect | Aov::SpecularIndirect | Aov::TransmissionIndirect | Aov::SubsurfaceIndirect => {
                self.indirect_parts().map_or(usize::MAX, |(total, _)| total.offset())
            }
            Aov::SampleCount | Aov::Variance | Aov::PrimId => usize::MAX,
        }
    }
}

const VALUES: usize = 11;
const EXTRA: usize = 30;

/// One camera sample's contribution to every AOV.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PixelSample {
    /// Radiance.
    pub radiance: Vec3,
    /// Coverage: 1 when the camera ray hit a surface.
    pub alpha: f32,
    /// First-hit reflectance.
    pub albedo: Vec3,
    /// First-hit normal.
    pub normal: Vec3,
    /// First-hit depth.
    pub depth: f32,
    /// First-hit position.
    pub position: Vec3,
    /// The radiance split by what the first surface did: diffuse, specular, transmission,
    /// emission, subsurface (the order of [`Aov::COMPONENTS`]); they sum to `radiance`.
    pub components: [Vec3; 5],
    /// The direct parts of diffuse, specular, transmission and subsurface.
    pub direct: [Vec3; 4],
    /// 1 + the index of the prim the camera ray hit first, 0 for none.
    pub prim_id: u32,
}

/// A rectangle of pixels.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    /// Left column.
    pub x: u32,
    /// Top row.
    pub y: u32,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
}

/// Accumulated samples of one tile.
#[derive(Clone, Debug)]
pub struct TileFilm {
    /// Pixels covered.
    pub rect: Rect,
    sums: Vec<[f64; VALUES]>,
    /// Position and light-path components, allocated only when asked for.
    extra: Vec<[f64; EXTRA]>,
    lum_sq: Vec<f64>,
    /// Samples each pixel has received.
    counts: Vec<u32>,
    /// The prim id of each pixel's first sample.
    prim_ids: Vec<u32>,
    /// Pixels still receiving samples (adaptive sampling turns them off).
    active: Vec<bool>,
    /// Samples per pixel scheduled so far (the most any pixel has).
    pub samples: u32,
}

impl TileFilm {
    /// An empty tile; `extra` allocates the position and light-path AOVs.
    pub fn new(rect: Rect, extra: bool) -> Self {
        let n = (rect.width * rect.height) as usize;
        let extra = if extra { vec![[0.0; EXTRA]; n] } else { Vec::new() };
        TileFilm {
            rect,
            sums: vec![[0.0; VALUES]; n],
            extra,
            lum_sq: vec![0.0; n],
            counts: vec![0; n],
            prim_ids: vec![0; n],
            active: vec![true; n],
            samples: 0,
        }
    }

    /// Empties the film and makes it cover `rect`, keeping its allocations (a worker's
    /// per-pass scratch film is reset for every tile it renders).
    pub fn reset(&mut self, rect: Rect, extra: bool) {
        let n = (rect.width * rect.height) as usize;
        self.rect = rect;
        self.sums.clear();
        self.sums.resize(n, [0.0; VALUES]);
        self.extra.clear();
        self.extra.resize(if extra { n } else { 0 }, [0.0; EXTRA]);
        for v in [&mut self.counts, &mut self.prim_ids] {
            v.clear();
            v.resize(n, 0);
        }
        self.lum_sq.clear();
        self.lum_sq.resize(n, 0.0);
        self.active.clear();
        self.active.resize(n, true);
        self.samples = 0;
    }

    /// Adds the sums of `pass`, a film over a rect inside this one, pixel by pixel: the film
    /// then holds (its sums) + (the pass's sums). Every pixel's total is built this way, one
    /// whole pass at a time in sample order, so a film assembled from the passes of separate
    /// sample ranges, or resumed from a checkpoint, holds the same f64 bits as one render.
    pub fn absorb(&mut self, pass: &TileFilm) {
        let (r, p) = (self.rect, pass.rect);
        assert!(p.x >= r.x && p.y >= r.y && p.x + p.width <= r.x + r.width && p.y + p.height <= r.y + r.height, "pass outside the film");
        assert_eq!(pass.has_extra(), self.has_extra(), "a pass with other AOV buffers than the film");
        for row in 0..p.height {
            for col in 0..p.width {
                let j = (row * p.width + col) as usize;
                let i = ((p.y - r.y + row) * r.width + (p.x - r.x + col)) as usize;
                self.absorb_pixel(i, pass, j);
            }
        }
    }

    fn absorb_pixel(&mut self, i: usize, pass: &TileFilm, j: usize) {
        for (acc, x) in self.sums[i].iter_mut().zip(pass.sums[j]) {
            *acc += x;
        }
        if let (Some(acc), Some(x)) = (self.extra.get_mut(i), pass.extra.get(j)) {
            for (a, x) in acc.iter_mut().zip(x) {
                *a += x;
            }
        }
        self.lum_sq[i] += pass.lum_sq[j];
        if self.counts[i] == 0 {
            self.prim_ids[i] = pass.prim_ids[j];
        }
        self.counts[i] += pass.counts[j];
    }

    /// The accumulated state as bytes (little-endian; per pixel its sums, extra sums when
    /// allocated, squared luminance, sample count and prim id): what a checkpoint or a
    /// sample-range slice stores and what the wire carries for one. Adaptive sampling's
    /// retired pixels are not included (slices and checkpoints render without it).
    pub fn encode(&self) -> Vec<u8> {
        let per_pixel = Self::encoded_bytes_per_pixel(self.has_extra());
        let mut out = Vec::with_capacity(self.counts.len() * per_pixel);
        for i in 0..self.counts.len() {
            let extra = self.extra.get(i).map_or(&[][..], |e| &e[..]);
            for v in self.sums[i].iter().chain(extra).chain([&self.lum_sq[i]]) {
                out.extend_from_slice(&v.to_le_bytes());
            }
            out.extend_from_slice(&self.counts[i].to_le_bytes());
            out.extend_from_slice(&self.prim_ids[i].to_le_bytes());
        }
        out
    }

    /// Bytes [`Self::encode`] writes per pixel.
    pub const fn encoded_bytes_per_pixel(extra: bool) -> usize {
        (VALUES + if extra { EXTRA } else { 0 } + 1) * 8 + 8
    }

    /// The film [`Self::encode`] wrote for `rect`; `None` when `bytes` has another length or
    /// a value is not finite (a damaged file or a stream from something else).
    pub fn decode(rect: Rect, extra: bool, samples: u32, bytes: &[u8]) -> Option<TileFilm> {
        let per_pixel = Self::encoded_bytes_per_pixel(extra);
        let n = rect.width as usize * rect.height as usize;
        if bytes.len() != n.checked_mul(per_pixel)? {
            return None;
        }
        let mut film = TileFilm::new(rect, extra);
        let f64_at = |b: &[u8], k: usize| f64::from_le_bytes(b[8 * k..8 * k + 8].try_into().expect("8 bytes"));
        for (i, b) in bytes.chunks_exact(per_pixel).enumerate() {
            let values = per_pixel / 8 - 1;
            if (0..values).any(|k| !f64_at(b, k).is_finite()) {
                return None;
            }
            film.sums[i] = std::array::from_fn(|k| f64_at(b, k));
            if let Some(e) = film.extra.get_mut(i) {
                *e = std::array::from_fn(|k| f64_at(b, VALUES + k));
            }
            film.lum_sq[i] = f64_at(b, values - 1);
            film.counts[i] = u32::from_le_bytes(b[8 * values..8 * values + 4].try_into().expect("4 bytes"));
            film.prim_ids[i] = u32::from_le_bytes(b[8 * values + 4..8 * values + 8].try_into().expect("4 bytes"));
        }
        film.samples = samples;
        Some(film)
    }

    /// Bytes one pixel of a tile holds (the server's memory budget reserves a film's
    /// `width × height ×` this before allocating it).
    pub const fn bytes_per_pixel(extra: bool) -> u64 {
        let extra = if extra { EXTRA * 8 } else { 0 };
        (VALUES * 8 + extra + 8 + 4 + 4 + 1) as u64
    }

    /// True when the tile records the position and light-path AOVs.
    pub fn has_extra(&self) -> bool {
        !self.extra.is_empty()
    }

    /// Adds one sample to local pixel `i` (row-major within the tile). Non-finite
    /// radiance never reaches the film: it is counted as zero and reported by the caller.
    #[inline]
    pub fn add(&mut self, i: usize, s: &PixelSample) {
        let v = [
            s.radiance.x,
            s.radiance.y,
            s.radiance.z,
            s.alpha,
            s.albedo.x,
            s.albedo.y,
            s.albedo.z,
            s.normal.x,
            s.normal.y,
            s.normal.z,
            s.depth,
        ];
        let sums = &mut self.sums[i];
        for (acc, x) in sums.iter_mut().zip(v) {
            *acc += x as f64;
        }
        let l = luminance(s.radiance) as f64;
        self.lum_sq[i] += l * l;
        if self.counts[i] == 0 {
            self.prim_ids[i] = s.prim_id;
        }
        self.counts[i] += 1;
        if let Some(extra) = self.extra.get_mut(i) {
            let vs = std::iter::once(s.position).chain(s.components).chain(s.direct);
            for (k, v) in vs.enumerate() {
                extra[3 * k] += v.x as f64;
                extra[3 * k + 1] += v.y as f64;
                extra[3 * k + 2] += v.z as f64;
            }
        }
    }

    /// True when pixel `i` still receives samples.
    #[inline]
    pub fn is_active(&self, i: usize) -> bool {
        self.active[i]
    }

    /// Number of pixels still receiving samples, and the samples taken in the tile.
    pub fn sample_totals(&self) -> (usize, u64) {
        (self.active.iter().filter(|&&a| a).count(), self.counts.iter().map(|&c| c as u64).sum())
    }

    /// Mean and variance of the mean of pixel `i`'s luminance.
    fn luminance_stats(&self, i: usize) -> (f64, f64) {
        let n = self.counts[i] as f64;
        if n < 2.0 {
            return (0.0, 0.0);
        }
        let s = &self.sums[i];
        let mean = luminance(Vec3::new(s[0] as f32, s[1] as f32, s[2] as f32)) as f64 / n;
        let var = ((self.lum_sq[i] / n) - mean * mean).max(0.0) * n / (n - 1.0);
        (mean, var / n)
    }

    /// Relative standard error of each pixel's mean luminance, row-major over the tile: against
    /// the mean plus 1e-3, so black pixels converge at once and very dark ones by their
    /// absolute error.
    pub fn relative_errors(&self) -> Vec<f32> {
        (0..self.counts.len())
            .map(|i| {
                let (mean, var) = self.luminance_stats(i);
                (var.sqrt() / (mean + 1e-3)) as f32
            })
            .collect()
    }

    /// Adaptive sampling: turns off the pixels whose relative error, the worst over their 3×3
    /// neighbourhood in the image, is below `threshold` (one pixel's estimate alone is itself
    /// noisy, and a pixel that has not yet met a rare bright path looks converged). `errors`
    /// holds every pixel's [`Self::relative_errors`], row-major over an image `width` wide, so
    /// pixels on a tile's edge see their neighbours in the next tile, and the image does not
    /// depend on the tile size.
    pub fn retire_converged(&mut self, errors: &[f32], width: u32, threshold: f32) {
        let (w, h) = (width as i64, (errors.len() / width.max(1) as usize) as i64);
        let r = self.rect;
        for py in 0..r.height {
            for px in 0..r.width {
                let (x, y) = ((r.x + px) as i64, (r.y + py) as i64);
                let mut worst = 0.0f32;
                for ny in (y - 1).max(0)..=(y + 1).min(h - 1) {
                    for nx in (x - 1).max(0)..=(x + 1).min(w - 1) {
                        worst = worst.max(errors[(ny * w + nx) as usize]);
                    }
                }
                if worst < threshold {
                    self.active[(py * r.width + px) as usize] = false;
                }
            }
        }
    }

    /// Mean of `aov` over the samples so far, row-major, channels interleaved.
    pub fn resolve(&self, aov: Aov) -> Vec<f32> {
        let c = aov.channels();
        match aov {
            Aov::SampleCount => return self.counts.iter().map(|&n| n as f32).collect(),
            Aov::Variance => return (0..self.counts.len()).map(|i| self.luminance_stats(i).1 as f32).collect(),
            Aov::PrimId => return self.prim_ids.iter().map(|&id| id as f32).collect(),
            _ => {}
        }
        let o = aov.offset();
        let count = |i: usize| self.counts[i].max(1) as f64;
        if aov.is_extra() {
            let o = o - VALUES;
            // An indirect part subtracts its direct part from the total.
            let d = aov.indirect_parts().map(|(_, direct)| direct.offset() - VALUES);
            return match self.extra.is_empty() {
                true => vec![0.0; self.sums.len() * c],
                false => self
                    .extra
                    .iter()
                    .enumerate()
                    .flat_map(|(i, s)| (0..c).map(move |k| ((s[o + k] - d.map_or(0.0, |d| s[d + k])) / count(i)) as f32))
                    .collect(),
            };
        }
        let mut out = Vec::with_capacity(self.sums.len() * c);
        for (i, s) in self.sums.iter().enumerate() {
            let n = count(i);
            if aov == Aov::Normal {
                // Average normals are renormalised so the AOV holds unit vectors.
                let v = Vec3::new(s[o] as f32, s[o + 1] as f32, s[o + 2] as f32).normalize_or_zero();
                out.extend_from_slice(&[v.x, v.y, v.z]);
            } else {
                out.extend((0..c).map(|k| (s[o + k] / n) as f32));
            }
        }
        out
    }

    /// Sum over pixels of (variance of the mean of luminance, mean luminance), for the
    /// noise estimate.
    pub fn noise_terms(&self) -> (f64, f64) {
        if self.samples < 2 {
            return (0.0, 0.0);
        }
        (0..self.counts.len()).map(|i| self.luminance_stats(i)).fold((0.0, 0.0), |(v, m), (mean, var)| (v + var, m + mean))
    }
}

/// Splits an image into tiles ordered from the centre outwards.
pub fn tiles_centre_out(width: u32, height: u32, size: u32) -> Vec<Rect> {
    let size = size.max(1);
    let mut tiles = Vec::new();
    for y in (0..height).step_by(size as usize) {
        for x in (0..width).step_by(size as usize) {
            tiles.push(Rect { x, y, width: size.min(width - x), height: size.min(height - y) });
        }
    }
    let (cx, cy) = (width as f32 / 2.0, height as f32 / 2.0);
    let d = |r: &Rect| {
        let dx = r.x as f32 + r.width as f32 / 2.0 - cx;
        let dy = r.y as f32 + r.height as f32 / 2.0 - cy;
        dx * dx + dy * dy
    };
    tiles.sort_by(|a, b| d(a).total_cmp(&d(b)).then((a.y, a.x).cmp(&(b.y, b.x))));
    tiles
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_the_image_once_and_start_in_the_middle() {
        let tiles = tiles_centre_out(100, 70, 32);
        let mut covered = vec![0u8; 100 * 70];
        for t in &tiles {
            for y in t.y..t.y + t.height {
                for x in t.x..t.x + t.width {
                    covered[(y * 100 + x) as usize] += 1;
                }
            }
        }
        assert!(covered.iter().all(|&c| c == 1));
        let first = tiles[0];
        assert!(first.x <= 50 && 50 <= first.x + first.width && first.y <= 35 && 35 <= first.y + first.height);
    }

    #[test]
    fn resolve_averages_and_renormalises_normals() {
        let mut f = TileFilm::new(Rect { x: 0, y: 0, width: 1, height: 1 }, false);
        f.add(0, &PixelSample { radiance: Vec3::ONE, alpha: 1.0, albedo: Vec3::ONE, normal: Vec3::Z, depth: 2.0, ..Default::default() });
        f.add(0, &PixelSample { radiance: Vec3::ZERO, alpha: 0.0, albedo: Vec3::ZERO, normal: Vec3::Z, depth: 4.0, ..Default::default() });
        f.samples = 2;
        assert_eq!(f.resolve(Aov::Beauty), vec![0.5, 0.5, 0.5, 0.5]);
        assert_eq!(f.resolve(Aov::Normal), vec![0.0, 0.0, 1.0]);
        assert_eq!(f.resolve(Aov::Depth), vec![3.0]);
        assert_eq!(f.resolve(Aov::SampleCount), vec![2.0]);
        // Luminance 1 and 0: sample variance 0.5, so the mean's variance is 0.25.
        assert!((f.resolve(Aov::Variance)[0] - 0.25).abs() < 1e-6);
    }

    /// Pixels retire only when they and their neighbours are below the threshold, and each
    /// pixel's mean uses its own sample count.
    #[test]
    fn converged_neighbourhoods_retire_and_means_use_their_own_counts() {
        let mut f = TileFilm::new(Rect { x: 0, y: 0, width: 5, height: 1 }, false);
        for k in 0..16 {
            for i in 0..5 {
                // Pixel 0 is noisy, the others constant.
                let v = if i == 0 { (k % 2) as f32 } else { 0.5 };
                f.add(i, &PixelSample { radiance: Vec3::splat(v), ..Default::default() });
            }
        }
        f.samples = 16;
        f.retire_converged(&f.relative_errors(), 5, 0.01);
        assert_eq!((0..5).map(|i| f.is_active(i)).collect::<Vec<_>>(), vec![true, true, false, false, false]);
        for _ in 0..16 {
            f.add(0, &PixelSample { radiance: Vec3::splat(1.0), ..Default::default() });
        }
        f.samples = 32;
        let beauty = f.resolve(Aov::Beauty);
        assert!((beauty[0] - 0.75).abs() < 1e-6 && (beauty[4] - 0.5).abs() < 1e-6, "{beauty:?}");
        assert_eq!(f.resolve(Aov::SampleCount), vec![32.0, 16.0, 16.0, 16.0, 16.0]);
    }

    /// Neighbourhoods cross tile edges: a noisy pixel on the right edge of one tile keeps the
    /// left edge of the next one sampling, as it would inside a single tile.
    #[test]
    fn neighbourhoods_reach_into_the_next_tile() {
        let mut tiles = [0, 3].map(|x| TileFilm::new(Rect { x, y: 0, width: 3, height: 1 }, false));
        for k in 0..16 {
            for (t, tile) in tiles.iter_mut().enumerate() {
                for i in 0..3 {
                    // Pixel 2 of the first tile (image column 2) is noisy.
                    let v = if t == 0 && i == 2 { (k % 2) as f32 } else { 0.5 };
                    tile.add(i, &PixelSample { radiance: Vec3::splat(v), ..Default::default() });
                }
            }
        }
        let errors: Vec<f32> = tiles.iter().flat_map(|t| t.relative_errors()).collect();
        for tile in &mut tiles {
            tile.retire_converged(&errors, 6, 0.01);
        }
        let active: Vec<bool> = tiles.iter().flat_map(|t| (0..3).map(|i| t.is_active(i))).collect();
        assert_eq!(active, vec![false, true, true, true, false, false]);
    }
}
