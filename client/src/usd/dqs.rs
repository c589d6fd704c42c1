//! Dual-quaternion skinning, as UsdSkel defines it (`skel:skinningMethod = "dualQuaternion"`;
//! UsdSkel's `UsdSkelSkinPoints`): each joint's skinning transform is split into a rotation
//! (the orthogonal polar factor of its linear part), a translation, and what remains of the
//! linear part (scale and shear). Points take the remainders blended linearly, then the
//! rotations and translations blended as dual quaternions (Kavan et al., "Skinning with Dual
//! Quaternions", I3D 2007), each flipped onto the hemisphere of the point's heaviest joint.

use glam::{DMat3, DMat4, DQuat, DVec3};

/// One joint's skinning transform, split.
#[derive(Clone, Copy, Debug)]
pub(super) struct DualJoint {
    /// Unit rotation quaternion (real part).
    real: DQuat,
    /// ½·t·real (dual part).
    dual: DQuat,
    /// The linear part left once the rotation is taken out: `linear = rotation · scale`.
    scale: DMat3,
}

impl DualJoint {
    /// Splits `m` (column-vector convention).
    pub(super) fn new(m: DMat4) -> Self {
        let linear = DMat3::from_mat4(m);
        let rotation = polar_rotation(linear);
        let real = DQuat::from_mat3(&rotation).normalize();
        let t = m.w_axis.truncate();
        DualJoint { real, dual: DQuat::from_xyzw(t.x, t.y, t.z, 0.0) * real * 0.5, scale: rotation.transpose() * linear }
    }

    /// True when the joint scales or shears (beyond 1e-6, as UsdSkel tests it).
    fn scales(&self) -> bool {
        !self.scale.abs_diff_eq(DMat3::IDENTITY, 1e-6)
    }
}

/// The orthogonal polar factor of `a` by Higham's Newton iteration U ← (U + U⁻ᵀ)/2; the
/// identity for a singular matrix (UsdSkel's factoring fails there too and drops the joint's
/// rotation).
fn polar_rotation(a: DMat3) -> DMat3 {
    if !(a.determinant().abs() > 1e-12) {
        return DMat3::IDENTITY;
    }
    let mut u = a;
    for _ in 0..64 {
        let next = (u + u.inverse().transpose()) * 0.5;
        let done = next.abs_diff_eq(u, 1e-15);
        u = next;
        if done {
            break;
        }
    }
    u
}

/// A blend of joints for one point: influences (joint, weight).
pub(super) struct Blend<'j> {
    pub joints: &'j [DualJoint],
    /// Any joint scales: remainders are blended (else the point is left as bound).
    pub any_scale: bool,
}

impl<'j> Blend<'j> {
    pub(super) fn new(joints: &'j [DualJoint]) -> Self {
        Blend { joints, any_scale: joints.iter().any(DualJoint::scales) }
    }

    /// What `influences` blend to: the rotation and translation of their dual quaternions, and
    /// their remainders blended linearly (none when no joint scales).
    pub(super) fn skinning(&self, influences: &[(usize, f64)]) -> Skinning {
        // The heaviest joint (the first of equals) sets the hemisphere.
        let pivot = influences.iter().fold(None, |best: Option<(usize, f64)>, &(j, w)| match best {
            Some((_, bw)) if bw >= w => best,
            _ => Some((j, w)),
        });
        let pivot = pivot.map_or(DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0), |(j, _)| self.joints[j].real);
        let zero = DQuat::from_xyzw(0.0, 0.0, 0.0, 0.0);
        let (mut real, mut dual, mut scale) = (zero, zero, DMat3::ZERO);
        for &(j, w) in influences.iter().filter(|(_, w)| *w != 0.0) {
            let joint = &self.joints[j];
            scale += joint.scale * w;
            let w = if joint.real.dot(pivot) < 0.0 { -w } else { w };
            real += joint.real * w;
            dual += joint.dual * w;
        }
        let len = real.length();
        if !(len > 0.0) {
            return Skinning { rotation: DQuat::IDENTITY, translation: DVec3::ZERO, scale: None };
        }
        let (real, dual) = (real * (1.0 / len), dual * (1.0 / len));
        let dual = dual - real * real.dot(dual);
        let t = dual * real.conjugate() * 2.0;
        Skinning { rotation: real, translation: DVec3::new(t.x, t.y, t.z), scale: self.any_scale.then_some(scale) }
    }
}

/// One point's blended skinning.
#[derive(Clone, Copy, Debug)]
pub(super) struct Skinning {
    rotation: DQuat,
    translation: DVec3,
    /// The blended scale and shear, applied first; `None` when no joint scales.
    scale: Option<DMat3>,
}

impl Skinning {
    /// `p` (already through the geometry's bind transform) skinned.
    pub(super) fn point(&self, p: DVec3) -> DVec3 {
        self.rotation * self.scale.map_or(p, |s| s * p) + self.translation
    }

    /// A normal (already through the bind transform's inverse transpose) turned by the
    /// rotation after the scale's inverse transpose.
    pub(super) fn normal(&self, n: DVec3) -> DVec3 {
        let n = match self.scale {
            Some(s) if s.determinant().abs() > 1e-300 => s.inverse().transpose() * n,
            _ => n,
        };
        (self.rotation * n).normalize_or_zero()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_joint_moves_points_as_its_matrix_does() {
        let m = DMat4::from_scale_rotation_translation(DVec3::new(2.0, 0.5, 1.5), DQuat::from_rotation_y(1.1), DVec3::new(1.0, -2.0, 3.0));
        let joints = [DualJoint::new(m)];
        let blend = Blend::new(&joints);
        let p = DVec3::new(0.3, -0.7, 1.9);
        assert!((blend.skinning(&[(0, 1.0)]).point(p) - m.transform_point3(p)).length() < 1e-12);
    }

    /// Two joints turned ±60° about z with equal weights: linear blending collapses the point
    /// towards the axis (cos 60° of its radius); dual quaternions keep its radius.
    #[test]
    fn an_even_blend_of_two_turns_keeps_the_radius() {
        let turn = |a: f64| DualJoint::new(DMat4::from_rotation_z(a));
        let joints = [turn(std::f64::consts::FRAC_PI_3), turn(-std::f64::consts::FRAC_PI_3)];
        let p = Blend::new(&joints).skinning(&[(0, 0.5), (1, 0.5)]).point(DVec3::X);
        assert!((p - DVec3::X).length() < 1e-9, "{p}");
        // Opposite hemispheres (a quaternion and its negation are one rotation) blend alike.
        let mut flipped = joints;
        flipped[1].real = -flipped[1].real;
        flipped[1].dual = -flipped[1].dual;
        assert!((Blend::new(&flipped).skinning(&[(0, 0.5), (1, 0.5)]).point(DVec3::X) - DVec3::X).length() < 1e-9);
    }

    #[test]
    fn a_singular_joint_degrades_without_nan() {
        let joints = [DualJoint::new(DMat4::from_scale(DVec3::ZERO))];
        let p = Blend::new(&joints).skinning(&[(0, 1.0)]).point(DVec3::ONE);
        assert!(p.is_finite());
        assert!(Blend::new(&joints).skinning(&[]).point(DVec3::ONE).is_finite());
    }
}
