//! A density over the unit square proportional to a grid's bilinear interpolation, sampled
//! exactly: the dome's importance sampling follows the radiance its bilinear lookups return.
//!
//! A piecewise-constant density over the texels (pbrt's, *Physically Based Rendering*, 3rd ed.,
//! section 14.2.4) leaves a ratio of radiance to density that varies across each texel, and
//! across its neighbours where the lookup spreads a bright texel: under a 64 × 32 sky whose sun
//! is one texel, a diffuse plane's direct light had twenty times the variance of Mitsuba 3's,
//! which warps its samples by the bilinear interpolant (`Hierarchical2D`, "Mitsuba 3: warp
//! functions"). Here the marginal density along the rows is piecewise linear between row
//! centres, each row's density piecewise linear between texel centres, and a conditional row
//! is a blend of two rows, drawn as a mixture: every step inverts a linear density in closed
//! form, so the density of a sample is the interpolant itself.

use glam::Vec2;

use crate::sampling::Distribution1D;
use crate::texture::Wrap;

/// The grid's nodes sit at cell centres, as a texture's texels do: wrapped around in `s`
/// (repeat), held constant beyond the first and last row centres in `v` (clamp), so the
/// interpolant is the one a `[Repeat, Clamp]` bilinear lookup reads.
#[derive(Debug)]
pub(super) struct Bilinear2D {
    width: usize,
    height: usize,
    /// Row-major node values, row 0 at `v` = 0.
    nodes: Vec<f32>,
    /// Row `j`'s density over its `width` spans (node `i` to node `i + 1`, wrapping).
    rows: Vec<Distribution1D>,
    /// Each row's integral in cell units (the sum of its nodes).
    row_sums: Vec<f32>,
    /// Over `height + 1` pieces of `v`: the half cell above the first row centre, the spans
    /// between row centres, and the half cell below the last.
    marginal: Distribution1D,
    /// The integral over the square in cell units (the sum of all nodes).
    total: f32,
}

impl Bilinear2D {
    /// The distribution of `nodes`, `height` rows of `width` non-negative finite values with a
    /// positive sum.
    pub fn new(width: usize, height: usize, nodes: Vec<f32>) -> Self {
        assert!(width > 0 && height > 0 && nodes.len() == width * height, "a {width} × {height} grid");
        let rows: Vec<Distribution1D> = nodes
            .chunks(width)
            .map(|row| Distribution1D::new(&(0..width).map(|i| 0.5 * (row[i] + row[(i + 1) % width])).collect::<Vec<_>>()))
            .collect();
        let row_sums: Vec<f32> = nodes.chunks(width).map(|row| row.iter().map(|&x| x as f64).sum::<f64>() as f32).collect();
        let pieces: Vec<f32> = std::iter::once(0.5 * row_sums[0])
            .chain(row_sums.windows(2).map(|r| 0.5 * (r[0] + r[1])))
            .chain(std::iter::once(0.5 * row_sums[height - 1]))
            .collect();
        let total = row_sums.iter().map(|&x| x as f64).sum::<f64>() as f32;
        Bilinear2D { width, height, nodes, rows, row_sums, marginal: Distribution1D::new(&pieces), total }
    }

    /// A point (`s`, `v`) drawn with `u`, and its density over the unit square.
    pub fn sample(&self, u: Vec2) -> (Vec2, f32) {
        let (w, h) = (self.width, self.height);
        // Down the rows: a half-cell band at either end, or a span between two row centres.
        let (piece, frac, _) = self.marginal.sample_continuous(u.y);
        let (y, upper, lower, beta) = match piece {
            0 => (0.5 * frac, 0, 0, 0.0),
            p if p == h => (h as f32 - 0.5 + 0.5 * frac, h - 1, h - 1, 0.0),
            p => {
                let beta = invert_linear(self.row_sums[p - 1], self.row_sums[p], frac);
                (p as f32 - 0.5 + beta, p - 1, p, beta)
            }
        };
        // Across: the row at `y` blends two rows; draw one by its share of the blend's
        // integral, reusing u.x within the choice (stratification kept), then a span of it.
        let (a, b) = ((1.0 - beta) * self.row_sums[upper], beta * self.row_sums[lower]);
        let share = if a + b > 0.0 { a / (a + b) } else { 1.0 };
        let (row, ux) = match u.x < share {
            true => (upper, u.x / share),
            false => (lower, (u.x - share) / (1.0 - share)),
        };
        let (span, frac, _) = self.rows[row].sample_continuous(ux.clamp(0.0, 1.0 - f32::EPSILON));
        let at = |i: usize| self.nodes[row * w + i % w];
        let x = (span as f32 + 0.5 + invert_linear(at(span), at(span + 1), frac)).rem_euclid(w as f32);
        let st = Vec2::new((x / w as f32).min(1.0 - f32::EPSILON), (y / h as f32).min(1.0 - f32::EPSILON));
        (st, self.density(st))
    }

    /// Nodes along `s`.
    #[cfg(test)]
    pub fn width(&self) -> usize {
        self.width
    }

    /// The density at (`s`, `v`) over the unit square: the interpolant over its integral.
    pub fn density(&self, st: Vec2) -> f32 {
        if !(self.total > 0.0) {
            return 0.0;
        }
        self.interpolate(st) * (self.width * self.height) as f32 / self.total
    }

    /// The bilinear interpolant at (`s`, `v`), as a `[Repeat, Clamp]` texture lookup reads it.
    fn interpolate(&self, st: Vec2) -> f32 {
        let (w, h) = (self.width, self.height);
        let x = st.x as f64 * w as f64 - 0.5;
        let y = st.y as f64 * h as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0 as i64, y0 as i64);
        // The texture's own wrapping (neither mode is black, so every index exists).
        let xs = [x0, x0 + 1].map(|i| Wrap::Repeat.index(i, w).unwrap_or(0));
        let ys = [y0, y0 + 1].map(|j| Wrap::Clamp.index(j, h).unwrap_or(0));
        let node = |i: usize, j: usize| self.nodes[ys[j] * self.width + xs[i]];
        let top = node(0, 0) + (node(1, 0) - node(0, 0)) * fx;
        let bottom = node(0, 1) + (node(1, 1) - node(0, 1)) * fx;
        (top + (bottom - top) * fy).max(0.0)
    }
}

/// The t in [0, 1) at which the density ∝ (1 − t)·a + t·b on [0, 1] has cumulative share `u`:
/// the root of a·t + (b − a)·t²/2 = u·(a + b)/2, in the form without cancellation when a ≈ b.
fn invert_linear(a: f32, b: f32, u: f32) -> f32 {
    if !(a + b > 0.0) {
        return u;
    }
    let root = (a * a + u * (b * b - a * a)).max(0.0).sqrt();
    let t = if a + root > 0.0 { u * (a + b) / (a + root) } else { u };
    t.clamp(0.0, 1.0 - f32::EPSILON)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Pcg32;

    /// A grid with a one-node spike, zero rows and a floor.
    fn spiky(width: usize, height: usize) -> Bilinear2D {
        let mut nodes = vec![0.05f32; width * height];
        nodes[2.min(height - 1) * width + width / 3] = 400.0;
        nodes[(height - 1) * width + width - 1] = 7.0;
        if height > 4 {
            nodes[4 * width..5 * width].fill(0.0);
        }
        Bilinear2D::new(width, height, nodes)
    }

    /// The linear inversion puts share u of a linear density's mass below t.
    #[test]
    fn linear_densities_are_inverted_exactly() {
        for (a, b) in [(1.0f32, 1.0f32), (0.0, 1.0), (1.0, 0.0), (3.0, 1e-6), (2.0, 2.0001)] {
            for k in 0..=16 {
                let u = k as f32 / 16.0 * (1.0 - f32::EPSILON);
                let t = invert_linear(a, b, u);
                let mass = (a * t + 0.5 * (b - a) * t * t) / (0.5 * (a + b));
                assert!((mass - u).abs() < 2e-6, "a {a} b {b}: u {u} → t {t}, mass {mass}");
            }
        }
    }

    /// The density integrates to one, and each sample reports the density it was drawn with,
    /// for grids of one row or column and up.
    #[test]
    fn density_integrates_to_one_and_samples_report_it() {
        for (w, h) in [(1, 1), (1, 5), (6, 1), (16, 8), (33, 17)] {
            let d = spiky(w, h);
            let n = 1024;
            let mut integral = 0.0f64;
            for i in 0..n {
                for j in 0..n {
                    integral += d.density(Vec2::new((i as f32 + 0.5) / n as f32, (j as f32 + 0.5) / n as f32)) as f64;
                }
            }
            integral /= (n * n) as f64;
            assert!((integral - 1.0).abs() < 2e-3, "{w} × {h}: ∫ density = {integral}");
            let mut rng = Pcg32::new(w as u64, h as u64);
            for _ in 0..20_000 {
                let (st, pdf) = d.sample(rng.next_2d());
                assert!((0.0..1.0).contains(&st.x) && (0.0..1.0).contains(&st.y), "{st}");
                assert!(pdf > 0.0 && (pdf - d.density(st)).abs() <= 1e-5 * pdf, "{w} × {h}: {pdf} at {st}");
            }
        }
    }

    /// A χ² test of the samples against the density, over a 24 × 24 histogram (cells' expected
    /// counts by a 16 × 16 quadrature each): the draws follow the interpolant, the spike's
    /// tent included.
    #[test]
    fn samples_follow_the_density() {
        let d = spiky(16, 8);
        let (cells, n) = (24usize, 400_000usize);
        let mut counts = vec![0.0f64; cells * cells];
        let mut rng = Pcg32::new(9, 4);
        for _ in 0..n {
            let (st, _) = d.sample(rng.next_2d());
            counts[(st.y * cells as f32) as usize * cells + (st.x * cells as f32) as usize] += 1.0;
        }
        let q = 16;
        let (mut chi2, mut dof) = (0.0f64, 0);
        for cy in 0..cells {
            for cx in 0..cells {
                let mut mass = 0.0f64;
                for i in 0..q {
                    for j in 0..q {
                        let s = (cx as f32 + (i as f32 + 0.5) / q as f32) / cells as f32;
                        let v = (cy as f32 + (j as f32 + 0.5) / q as f32) / cells as f32;
                        mass += d.density(Vec2::new(s, v)) as f64;
                    }
                }
                let expected = mass / (q * q * cells * cells) as f64 * n as f64;
                if expected >= 5.0 {
                    chi2 += (counts[cy * cells + cx] - expected).powi(2) / expected;
                    dof += 1;
                }
            }
        }
        // The 0.999 quantile of χ² with k dof is below k + 3.1·√(2k) + 10 for k in the hundreds.
        let bound = dof as f64 + 3.1 * (2.0 * dof as f64).sqrt() + 10.0;
        assert!(chi2 < bound, "χ² = {chi2:.1} over {dof} cells (bound {bound:.1})");
    }
}
