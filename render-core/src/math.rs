//! Small vector helpers: orthonormal frames and colour utilities.

use glam::Vec3;

/// An orthonormal frame; `n` is the local +Z axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// Local +X (tangent).
    pub t: Vec3,
    /// Local +Y (bitangent).
    pub b: Vec3,
    /// Local +Z (normal).
    pub n: Vec3,
}

impl Frame {
    /// A frame around a unit normal, branchless and continuous except at one pole:
    /// Duff et al., "Building an Orthonormal Basis, Revisited", JCGT 2017.
    pub fn from_normal(n: Vec3) -> Self {
        let sign = 1.0f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        let t = Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x);
        let bt = Vec3::new(b, sign + n.y * n.y * a, -n.y);
        Frame { t, b: bt, n }
    }

    /// A frame whose tangent runs around `axis` (t ∥ axis × n), like lines of latitude around
    /// an object's up axis: continuous everywhere but where `n` is parallel to `axis`, where it
    /// falls back to [`Frame::from_normal`]. Anisotropic lobes need a tangent field without
    /// the seam the branchless basis has across the z = 0 plane.
    pub fn from_normal_around(n: Vec3, axis: Vec3) -> Self {
        let t = axis.cross(n);
        let len = t.length();
        if !(len > 1e-4 * axis.length()) {
            return Frame::from_normal(n);
        }
        let t = t / len;
        Frame { t, b: n.cross(t), n }
    }

    /// A frame whose tangent is `along` made perpendicular to `n` (a fibre's direction on its
    /// tube), or [`Frame::from_normal_around`] `fallback` where `along` is parallel to `n` or zero.
    pub fn from_normal_along(n: Vec3, along: Vec3, fallback: Vec3) -> Self {
        let t = along - n * n.dot(along);
        let len = t.length();
        if !(len > 1e-6 * along.length()) || !len.is_finite() {
            return Frame::from_normal_around(n, fallback);
        }
        let t = t / len;
        Frame { t, b: n.cross(t), n }
    }

    /// The frame turned about its normal by `turns` of a full turn, counter-clockwise seen
    /// from the normal's side (t towards b).
    pub fn turned(self, turns: f32) -> Self {
        if turns == 0.0 {
            return self;
        }
        let (sin, cos) = (turns * std::f32::consts::TAU).sin_cos();
        let t = (self.t * cos + self.b * sin).normalize_or(self.t);
        Frame { t, b: self.n.cross(t), n: self.n }
    }

    /// World direction to local coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    /// Local direction to world coordinates.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// A shading normal `n` bent towards the geometric normal `ng` (both on the viewer's side)
/// just enough that the mirror reflection of the view direction `wo` about it stays above the
/// surface. Far-tilted shading normals (normal maps, coarse smooth meshes) otherwise leave the
/// viewer below their own horizon and the surface renders black in stripes. The criterion
/// and threshold are Blender Cycles' `ensure_valid_specular_reflection` (reflection at least
/// min(0.9·(wo·ng), 0.01) above the surface); the bend here is found by bisection along the
/// arc from `ng` to `n` rather than in closed form.
pub fn valid_shading_normal(ng: Vec3, wo: Vec3, n: Vec3) -> Vec3 {
    let threshold = (0.9 * wo.dot(ng)).min(0.01);
    let reflects_above = |m: Vec3| (2.0 * wo.dot(m) * m - wo).dot(ng) >= threshold;
    if reflects_above(n) || wo.dot(ng) <= 0.0 {
        return n;
    }
    // ng itself reflects wo to wo·ng ≥ threshold above the surface; move from it towards n.
    let (mut lo, mut hi) = (0.0f32, 1.0f32);
    for _ in 0..20 {
        let mid = 0.5 * (lo + hi);
        if reflects_above(ng.lerp(n, mid).normalize_or(ng)) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    ng.lerp(n, lo).normalize_or(ng)
}

/// Rec.709 relative luminance of a linear RGB colour.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    c.dot(Vec3::new(0.2126, 0.7152, 0.0722))
}

/// True when every component is finite.
#[inline]
pub fn is_finite(v: Vec3) -> bool {
    v.x.is_finite() && v.y.is_finite() && v.z.is_finite()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_is_orthonormal_for_awkward_normals() {
        for n in [Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(1e-7, 0.0, -1.0).normalize(), Vec3::new(0.3, -0.4, 0.866).normalize()] {
            let f = Frame::from_normal(n);
            assert!((f.t.length() - 1.0).abs() < 1e-5);
            assert!((f.b.length() - 1.0).abs() < 1e-5);
            assert!(f.t.dot(f.b).abs() < 1e-5 && f.t.dot(n).abs() < 1e-5 && f.b.dot(n).abs() < 1e-5);
            let v = Vec3::new(0.2, -0.5, 0.7);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-5);
            // right-handed: t x b = n
            assert!((f.t.cross(f.b) - n).length() < 1e-4);
            let g = Frame::from_normal_around(n, Vec3::Y);
            assert!(g.t.dot(g.b).abs() < 1e-5 && g.t.dot(n).abs() < 1e-5 && (g.t.cross(g.b) - n).length() < 1e-4);
        }
    }

    /// Across the z = 0 plane the branchless basis turns its tangent round; the latitude
    /// frame does not (what made an anisotropic sphere split down the middle).
    #[test]
    fn latitude_frame_is_continuous_where_the_branchless_one_is_not() {
        let (a, b) = (Vec3::new(0.6, 0.8, 1e-3).normalize(), Vec3::new(0.6, 0.8, -1e-3).normalize());
        assert!(Frame::from_normal(a).t.dot(Frame::from_normal(b).t) < 0.5);
        assert!(Frame::from_normal_around(a, Vec3::Y).t.dot(Frame::from_normal_around(b, Vec3::Y).t) > 0.999);
    }
}
