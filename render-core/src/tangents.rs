//! MikkTSpace tangents (Mikkelsen, "Simulation of Wrinkled Surfaces Revisited", 2008), the
//! tangent space normal maps are baked in by Blender, Substance, xNormal and most of the
//! pipeline: per-vertex tangents welded across the triangles that share a position, normal
//! and texture coordinate, with the bitangent's sign per vertex. `bevy_mikktspace` is a
//! byte-identical port of the reference implementation.
//!
//! At a shading point the tangent is interpolated like the normal, and the map's vector
//! (x, y, z) becomes x·T + y·B + z·N with B = sign·(N × T), as the reference's pixel shader
//! does; per-triangle tangents (from ∂p/∂s) stand in where a mesh has none.

use bevy_mikktspace::{Geometry, TangentSpace, generate_tangents};
use glam::{Vec2, Vec3, Vec4};

use crate::geometry::{Attribute, Mesh};

struct Corners<'a> {
    mesh: &'a Mesh,
    out: Vec<Vec4>,
}

impl Corners<'_> {
    fn face_normal(&self, face: usize) -> Vec3 {
        let [a, b, c] = self.mesh.triangle(face);
        (b - a).cross(c - a).normalize_or(Vec3::Z)
    }
}

impl Geometry for Corners<'_> {
    fn num_faces(&self) -> usize {
        self.mesh.indices.len()
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.mesh.triangle(face)[vert].to_array()
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        let n = self.mesh.normals.corners(face, self.mesh.indices[face]).map(|c| c[vert]).unwrap_or_else(|| self.face_normal(face));
        n.normalize_or(self.face_normal(face)).to_array()
    }

    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        self.mesh.uvs.corners(face, self.mesh.indices[face]).map_or([0.0; 2], |c| c[vert].to_array())
    }

    fn set_tangent(&mut self, tangent_space: Option<TangentSpace>, face: usize, vert: usize) {
        // A corner MikkTSpace cannot give a tangent (a degenerate island) keeps zero, and
        // shading falls back to the triangle's own tangent there.
        self.out[3 * face + vert] = tangent_space.map_or(Vec4::ZERO, |t| Vec4::from_array(t.tangent_encoded()));
    }
}

/// Per-corner tangents of `mesh` (face-varying: xyz the unit tangent in object space, w the
/// bitangent sign), or None when it has no texture coordinates or MikkTSpace fails.
pub fn mikktspace(mesh: &Mesh) -> Option<Attribute<Vec4>> {
    if matches!(mesh.uvs, Attribute::None) || mesh.indices.is_empty() {
        return None;
    }
    let mut corners = Corners { mesh, out: vec![Vec4::ZERO; 3 * mesh.indices.len()] };
    generate_tangents(&mut corners).ok()?;
    Some(Attribute::FaceVarying(corners.out))
}

/// Which way a normal map's bitangent runs: MikkTSpace's sign, or the triangle's ∂p/∂t.
#[derive(Clone, Copy, Debug)]
pub enum Handedness {
    /// MikkTSpace's bitangent sign (the tangent's w).
    Sign(f32),
    /// The bitangent is on the side of N × T that ∂p/∂t is.
    Along(Vec3),
}

/// The shading normal a tangent-space normal map gives with tangent `t` (world space, any
/// length) around the shading normal `ns`: normalize(x·T + y·B + z·N) with T made orthogonal
/// to N and B = ±(N × T) by `handedness`. None when the tangent or the value is degenerate.
pub fn perturb(ns: Vec3, t: Vec3, handedness: Handedness, n_ts: Vec3) -> Option<Vec3> {
    let t = (t - ns * ns.dot(t)).try_normalize()?;
    if !n_ts.is_finite() {
        return None;
    }
    let flip = match handedness {
        Handedness::Sign(sign) => sign < 0.0,
        Handedness::Along(dpdt) => ns.cross(t).dot(dpdt) < 0.0,
    };
    let b = ns.cross(t) * if flip { -1.0 } else { 1.0 };
    (t * n_ts.x + b * n_ts.y + ns * n_ts.z).try_normalize()
}

/// The normal-mapped shading normal: with the interpolated MikkTSpace tangent `mikk` (xyz
/// and bitangent sign w) where the mesh has one, else with the triangle's own ∂p/∂s and
/// ∂p/∂t (MikkTSpace's construction, per triangle); `ns` where both are degenerate.
pub fn normal_mapped(ns: Vec3, mikk: Vec4, dpds: Vec3, dpdt: Vec3, n_ts: Vec3) -> Vec3 {
    let welded = (mikk != Vec4::ZERO).then(|| perturb(ns, mikk.truncate(), Handedness::Sign(mikk.w), n_ts)).flatten();
    welded.or_else(|| perturb(ns, dpds, Handedness::Along(dpdt), n_ts)).unwrap_or(ns)
}

/// The shading normal of a surface moved along `ns` by a height whose slope is `slope` (height
/// per unit of s and t): normalize(ns − ∇h), with ∇h = slope.s ∇s + slope.t ∇t, where ∇s and
/// ∇t are the dual basis of the triangle's ∂p/∂s and ∂p/∂t in the plane normal to `ns`.
/// Blinn's bump mapping ("Simulation of Wrinkled Surfaces", 1978) to first order in the
/// height, which drops the term of the normal's own change. `ns` where the derivatives are
/// degenerate (no texture coordinates) or the slope is not finite.
pub fn bumped(ns: Vec3, dpds: Vec3, dpdt: Vec3, slope: Vec2) -> Vec3 {
    let a = dpds - ns * ns.dot(dpds);
    let b = dpdt - ns * ns.dot(dpdt);
    let across_t = b.cross(ns);
    let det = a.dot(across_t);
    if det.abs() < f32::MIN_POSITIVE || !slope.is_finite() {
        return ns;
    }
    let gradient = (across_t * slope.x + ns.cross(a) * slope.y) / det;
    let tilted = ns - gradient;
    // Scaled to its largest component first, so a cliff's slope does not overflow the length.
    (tilted / tilted.abs().max_element()).try_normalize().unwrap_or(ns)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::Uvs;
    use glam::Vec2;

    /// The per-corner tangents as a plain list.
    fn corners(mesh: &Mesh) -> Vec<Vec4> {
        match mikktspace(mesh) {
            Some(Attribute::FaceVarying(v)) => v,
            other => panic!("{other:?}"),
        }
    }

    /// A unit square in the xy plane, two triangles sharing a diagonal, st = (x, y).
    fn square(uvs: impl Fn(Vec2) -> Vec2) -> Mesh {
        let p = [Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y];
        Mesh {
            positions: p.to_vec(),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            normals: Attribute::Vertex(vec![Vec3::Z; 4]),
            uvs: Uvs::Vertex(p.iter().map(|q| uvs(q.truncate())).collect()),
            ..Default::default()
        }
    }

    /// st along xy: the tangent is +x and the bitangent +y (sign +1) at every corner; st
    /// mirrored in s: the tangent is −x and the sign flips so the bitangent stays +y.
    #[test]
    fn tangents_follow_the_texture_axes_and_mirroring_flips_the_sign() {
        for t in corners(&square(|p| p)) {
            assert!((t - Vec4::new(1.0, 0.0, 0.0, 1.0)).abs().max_element() < 1e-5, "{t:?}");
        }
        for t in corners(&square(|p| Vec2::new(1.0 - p.x, p.y))) {
            assert!((t - Vec4::new(-1.0, 0.0, 0.0, -1.0)).abs().max_element() < 1e-5, "{t:?}");
        }
        let b = |t: Vec4| Vec3::Z.cross(t.truncate()) * t.w;
        assert!((b(corners(&square(|p| Vec2::new(1.0 - p.x, p.y)))[0]) - Vec3::Y).length() < 1e-5);
    }

    /// Welding: on a curved strip whose triangles meet at an angle, each shared vertex gets
    /// one tangent for all its triangles (per-triangle tangents would differ across the edge).
    #[test]
    fn shared_vertices_get_one_welded_tangent() {
        // A bent strip: two quads folded 40° along x = 1, st running along the fold's normal.
        let fold = |x: f32| if x <= 1.0 { Vec3::new(x, 0.0, 0.0) } else { Vec3::new(1.0 + (x - 1.0) * 0.766, 0.0, -(x - 1.0) * 0.643) };
        let mut positions = Vec::new();
        let mut st = Vec::new();
        for &x in &[0.0f32, 1.0, 2.0] {
            for &y in &[0.0f32, 1.0] {
                positions.push(fold(x) + Vec3::Y * y);
                st.push(Vec2::new(x, y));
            }
        }
        // Vertex (x index i, y index j) is 2i + j.
        let indices = vec![[0, 2, 3], [0, 3, 1], [2, 4, 5], [2, 5, 3]];
        let normals: Vec<Vec3> = positions
            .iter()
            .map(|p| {
                if p.x < 0.5 {
                    Vec3::Z
                } else if p.x < 1.5 {
                    (Vec3::Z + Vec3::new(0.643, 0.0, 0.766)).normalize()
                } else {
                    Vec3::new(0.643, 0.0, 0.766)
                }
            })
            .collect();
        let mesh =
            Mesh { positions, indices: indices.clone(), normals: Attribute::Vertex(normals), uvs: Uvs::Vertex(st), ..Default::default() };
        let t = corners(&mesh);
        // Vertex 2 (on the fold) appears in triangles 0, 2 and 3: one tangent for all.
        let at = |v: u32| -> Vec<Vec4> {
            let mut found = Vec::new();
            for (f, tri) in indices.iter().enumerate() {
                for (k, &i) in tri.iter().enumerate() {
                    if i == v {
                        found.push(t[3 * f + k]);
                    }
                }
            }
            found
        };
        let shared = at(2);
        assert!(shared.len() == 3 && shared.iter().all(|x| (*x - shared[0]).abs().max_element() < 1e-6), "{shared:?}");
        // It lies between the two faces' own tangents.
        let mid = (Vec3::X + Vec3::new(0.766, 0.0, -0.643)).normalize();
        assert!(shared[0].truncate().dot(mid) > 0.99, "{shared:?}");
    }

    /// The normal of the height field z = h(s, t) over a plane parameterised by p = s·a + t·b:
    /// with a sheared parameterisation the answer is still the height field's own normal.
    #[test]
    fn a_bump_tilts_the_normal_as_the_height_field_it_describes() {
        let ns = Vec3::Z;
        assert_eq!(bumped(ns, Vec3::X, Vec3::Y, Vec2::ZERO), ns, "no slope, no tilt");
        // h = 0.5·s with s along x (one unit of s a unit of x): z = 0.5·x, normal (−0.5, 0, 1).
        let n = bumped(ns, Vec3::X, Vec3::Y, Vec2::new(0.5, 0.0));
        assert!((n - Vec3::new(-0.5, 0.0, 1.0).normalize()).length() < 1e-6, "{n}");
        // s stretched over two units of x: the same height change over twice the run.
        let n = bumped(ns, Vec3::X * 2.0, Vec3::Y, Vec2::new(0.5, 0.0));
        assert!((n - Vec3::new(-0.25, 0.0, 1.0).normalize()).length() < 1e-6, "{n}");
        // Sheared: p = s·x + t·(x + y), h = 0.3·t. In x and y, t = y and s = x − y, so
        // z = 0.3·y and the normal is (0, −0.3, 1), whatever s does.
        let n = bumped(ns, Vec3::X, Vec3::X + Vec3::Y, Vec2::new(0.0, 0.3));
        assert!((n - Vec3::new(0.0, -0.3, 1.0).normalize()).length() < 1e-6, "{n}");
        // Derivatives with a component along the normal are taken in its plane.
        let n = bumped(ns, Vec3::new(1.0, 0.0, 0.7), Vec3::Y, Vec2::new(0.5, 0.0));
        assert!((n - Vec3::new(-0.5, 0.0, 1.0).normalize()).length() < 1e-6, "{n}");
        // A vertical cliff still gives a unit normal, in the plane.
        let n = bumped(ns, Vec3::X, Vec3::Y, Vec2::new(1e30, 0.0));
        assert!((n - -Vec3::X).length() < 1e-6, "{n}");
        // Degenerate: no texture coordinates, parallel derivatives, tiny scales, bad slopes.
        assert_eq!(bumped(ns, Vec3::ZERO, Vec3::ZERO, Vec2::ONE), ns);
        assert_eq!(bumped(ns, Vec3::X, Vec3::X * 2.0, Vec2::ONE), ns);
        assert_eq!(bumped(ns, Vec3::Z, Vec3::Y, Vec2::ONE), ns, "∂p/∂s along the normal");
        assert_eq!(bumped(ns, Vec3::X, Vec3::Y, Vec2::new(f32::NAN, 0.0)), ns);
        assert_eq!(bumped(ns, Vec3::X, Vec3::Y, Vec2::new(f32::INFINITY, 0.0)), ns);
        let tiny = bumped(ns, Vec3::X * 1e-20, Vec3::Y * 1e-20, Vec2::new(1e-20, 0.0));
        assert!(tiny.is_finite() && (tiny.length() - 1.0).abs() < 1e-6, "{tiny}");
    }

    #[test]
    fn perturbing_with_a_flat_map_keeps_the_normal_and_a_tilted_map_follows_the_tangent() {
        let ns = Vec3::Z;
        assert_eq!(perturb(ns, Vec3::X, Handedness::Sign(1.0), Vec3::Z), Some(Vec3::Z));
        let tilted = perturb(ns, Vec3::X * 3.0 + Vec3::Z, Handedness::Sign(1.0), Vec3::new(0.5, 0.0, 0.866)).unwrap();
        assert!((tilted - Vec3::new(0.5, 0.0, 0.866).normalize()).length() < 1e-4, "{tilted:?}");
        let mirrored = perturb(ns, Vec3::X, Handedness::Sign(-1.0), Vec3::new(0.0, 0.5, 0.866)).unwrap();
        assert!(mirrored.y < 0.0, "sign −1 flips the bitangent: {mirrored:?}");
        assert_eq!(perturb(ns, Vec3::Z, Handedness::Sign(1.0), Vec3::X), None, "a tangent along the normal is degenerate");
    }

    #[test]
    fn normal_maps_tilt_along_the_texture_axes_and_keep_their_handedness() {
        let (ns, dpds, dpdt) = (Vec3::Z, Vec3::X * 2.0, Vec3::Y * 3.0);
        assert_eq!(normal_mapped(ns, Vec4::ZERO, dpds, dpdt, Vec3::Z), Vec3::Z, "a flat map is the shading normal");
        let n = normal_mapped(ns, Vec4::ZERO, dpds, dpdt, Vec3::new(1.0, 0.0, 1.0));
        assert!((n - Vec3::new(1.0, 0.0, 1.0).normalize()).length() < 1e-6, "+x leans along ∂p/∂s: {n}");
        // A mirrored texture (t running down) flips the bitangent, as MikkTSpace's sign does.
        let up = normal_mapped(ns, Vec4::ZERO, dpds, dpdt, Vec3::new(0.0, 1.0, 1.0));
        let mirrored = normal_mapped(ns, Vec4::ZERO, dpds, -dpdt, Vec3::new(0.0, 1.0, 1.0));
        assert!(up.y > 0.0 && mirrored.y < 0.0, "{up} {mirrored}");
        // Degenerate frames and values keep the normal.
        assert_eq!(normal_mapped(ns, Vec4::ZERO, Vec3::Z, dpdt, Vec3::X), ns);
        assert_eq!(normal_mapped(ns, Vec4::ZERO, dpds, dpdt, Vec3::NAN), ns);
        assert_eq!(normal_mapped(ns, Vec4::ZERO, dpds, dpdt, Vec3::ZERO), ns);
    }
}
