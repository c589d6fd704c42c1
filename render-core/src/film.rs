//! The film: per-pixel sums of every AOV in f64 (as pbrt-v4's `RGBFilm` does), kept per
//! tile so each tile is owned by one worker at a time.

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
}

impl Aov {
    /// All AOVs.
    pub const ALL: [Aov; 4] = [Aov::Beauty, Aov::Albedo, Aov::Normal, Aov::Depth];

    /// The AOV's wire and file name.
    pub fn name(self) -> &'static str {
        match self {
            Aov::Beauty => "beauty",
            Aov::Albedo => "albedo",
            Aov::Normal => "normal",
            Aov::Depth => "depth",
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
            Aov::Albedo | Aov::Normal => 3,
            Aov::Depth => 1,
        }
    }

    fn offset(self) -> usize {
        match self {
            Aov::Beauty => 0,
            Aov::Albedo => 4,
            Aov::Normal => 7,
            Aov::Depth => 10,
        }
    }
}

const VALUES: usize = 11;

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
    lum_sq: Vec<f64>,
    /// Samples per pixel so far.
    pub samples: u32,
}

impl TileFilm {
    /// An empty tile.
    pub fn new(rect: Rect) -> Self {
        let n = (rect.width * rect.height) as usize;
        TileFilm { rect, sums: vec![[0.0; VALUES]; n], lum_sq: vec![0.0; n], samples: 0 }
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
    }

    /// Mean of `aov` over the samples so far, row-major, channels interleaved.
    pub fn resolve(&self, aov: Aov) -> Vec<f32> {
        let n = self.samples.max(1) as f64;
        let (o, c) = (aov.offset(), aov.channels());
        let mut out = Vec::with_capacity(self.sums.len() * c);
        for s in &self.sums {
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
        let n = self.samples as f64;
        if n < 2.0 {
            return (0.0, 0.0);
        }
        let mut var_sum = 0.0;
        let mut mean_sum = 0.0;
        for (s, &sq) in self.sums.iter().zip(&self.lum_sq) {
            let mean = luminance(Vec3::new(s[0] as f32, s[1] as f32, s[2] as f32)) as f64 / n;
            let var = ((sq / n) - mean * mean).max(0.0) * n / (n - 1.0);
            var_sum += var / n;
            mean_sum += mean;
        }
        (var_sum, mean_sum)
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
        let mut f = TileFilm::new(Rect { x: 0, y: 0, width: 1, height: 1 });
        f.add(0, &PixelSample { radiance: Vec3::ONE, alpha: 1.0, albedo: Vec3::ONE, normal: Vec3::Z, depth: 2.0 });
        f.add(0, &PixelSample { radiance: Vec3::ZERO, alpha: 0.0, albedo: Vec3::ZERO, normal: Vec3::Z, depth: 4.0 });
        f.samples = 2;
        assert_eq!(f.resolve(Aov::Beauty), vec![0.5, 0.5, 0.5, 0.5]);
        assert_eq!(f.resolve(Aov::Normal), vec![0.0, 0.0, 1.0]);
        assert_eq!(f.resolve(Aov::Depth), vec![3.0]);
    }
}
