//! `UsdGeomMesh` to triangles: polygon fan triangulation, winding, and normals in every
//! interpolation the slice supports.

use glam::Vec3;
use render_core::geometry::{Mesh, Normals};

/// Authored mesh data, straight from the stage.
pub struct MeshSource {
    /// `points`.
    pub points: Vec<Vec3>,
    /// `faceVertexCounts`.
    pub counts: Vec<i64>,
    /// `faceVertexIndices`.
    pub indices: Vec<i64>,
    /// `normals` (or `primvars:normals`, de-indexed) and their interpolation.
    pub normals: Option<(Vec<Vec3>, String)>,
    /// `orientation == leftHanded`.
    pub left_handed: bool,
    /// `subdivisionScheme != none`: smooth normals are computed when none are authored.
    pub smooth: bool,
}

/// Triangulates `src`; errors name the attribute at fault. Warnings go to `warn`.
pub fn triangulate(src: &MeshSource, warn: impl FnMut(String)) -> Result<Mesh, String> {
    triangulate_with_faces(src, warn).map(|(m, _)| m)
}

/// The triangles of `mesh` whose face (from [`triangulate_with_faces`]) `keep` accepts, as a
/// mesh of its own: same points, the kept triangles, their normals.
pub fn select_faces(mesh: &Mesh, face_of: &[u32], keep: impl Fn(u32) -> bool) -> Mesh {
    let kept: Vec<usize> = (0..mesh.indices.len()).filter(|&t| keep(face_of[t])).collect();
    let normals = match &mesh.normals {
        Normals::FaceVarying(n) => Normals::FaceVarying(kept.iter().flat_map(|&t| [n[3 * t], n[3 * t + 1], n[3 * t + 2]]).collect()),
        other => other.clone(),
    };
    Mesh { positions: mesh.positions.clone(), indices: kept.iter().map(|&t| mesh.indices[t]).collect(), normals }
}

/// [`triangulate`], also returning the authored face of each triangle.
pub fn triangulate_with_faces(src: &MeshSource, mut warn: impl FnMut(String)) -> Result<(Mesh, Vec<u32>), String> {
    let total: i64 = src.counts.iter().sum();
    if src.counts.iter().any(|&c| c < 0) || total != src.indices.len() as i64 {
        return Err(format!("faceVertexCounts add up to {total} but faceVertexIndices has {} entries", src.indices.len()));
    }
    let n = src.points.len() as i64;
    if let Some((i, &v)) = src.indices.iter().enumerate().find(|&(_, &v)| v < 0 || v >= n) {
        return Err(format!("faceVertexIndices[{i}] = {v} is out of range for {n} points"));
    }
    // Fan triangulation; (face, corner) of each triangle corner for face-varying data.
    let mut tris: Vec<[u32; 3]> = Vec::with_capacity(src.indices.len());
    let mut corners: Vec<[usize; 3]> = Vec::with_capacity(src.indices.len());
    let mut uniform_of: Vec<usize> = Vec::new();
    let mut base = 0usize;
    let mut degenerate_faces = 0;
    for (face, &count) in src.counts.iter().enumerate() {
        let count = count as usize;
        if count < 3 {
            degenerate_faces += 1;
        }
        for k in 1..count.saturating_sub(1) {
            let c = if src.left_handed { [base, base + k + 1, base + k] } else { [base, base + k, base + k + 1] };
            tris.push(c.map(|i| src.indices[i] as u32));
            corners.push(c);
            uniform_of.push(face);
        }
        base += count;
    }
    if degenerate_faces > 0 {
        warn(format!("{degenerate_faces} face(s) with fewer than 3 vertices skipped"));
    }

    let normals = match &src.normals {
        None if src.smooth => Normals::Vertex(smooth_normals(&src.points, &tris)),
        None => Normals::None,
        Some((n, interp)) => {
            let mut expect = |want: usize| -> bool {
                if n.len() == want {
                    true
                } else {
                    warn(format!("normals: {} values for {interp} interpolation, {want} expected; ignoring them", n.len()));
                    false
                }
            };
            match interp.as_str() {
                "vertex" | "varying" if expect(src.points.len()) => Normals::Vertex(n.clone()),
                "faceVarying" if expect(src.indices.len()) => Normals::FaceVarying(corners.iter().flat_map(|c| c.map(|i| n[i])).collect()),
                "uniform" if expect(src.counts.len()) => Normals::FaceVarying(uniform_of.iter().flat_map(|&f| [n[f]; 3]).collect()),
                "constant" if expect(1) => Normals::FaceVarying(vec![n[0]; 3 * tris.len()]),
                "vertex" | "varying" | "faceVarying" | "uniform" | "constant" => Normals::None,
                other => {
                    warn(format!("normals: unknown interpolation '{other}'; ignoring them"));
                    Normals::None
                }
            }
        }
    };
    let normals = match normals {
        // Bad normals (zero length, NaN) are repaired to the geometric normal at shading
        // time; say so once.
        Normals::Vertex(ref v) | Normals::FaceVarying(ref v) if v.iter().any(|n| !n.is_finite() || n.length_squared() == 0.0) => {
            warn("normals: some are zero-length or not finite; the geometric normal is used there".into());
            normals
        }
        other => other,
    };
    let face_of = uniform_of.iter().map(|&f| f as u32).collect();
    Ok((Mesh { positions: src.points.clone(), indices: tris, normals }, face_of))
}

/// Area-weighted vertex normals.
fn smooth_normals(points: &[Vec3], tris: &[[u32; 3]]) -> Vec<Vec3> {
    let mut n = vec![Vec3::ZERO; points.len()];
    for t in tris {
        let [a, b, c] = t.map(|i| points[i as usize]);
        let face = (b - a).cross(c - a);
        for &i in t {
            n[i as usize] += face;
        }
    }
    n.into_iter().map(|v| v.normalize_or_zero()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad(left_handed: bool, normals: Option<(Vec<Vec3>, String)>) -> MeshSource {
        MeshSource {
            points: vec![Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y],
            counts: vec![4],
            indices: vec![0, 1, 2, 3],
            normals,
            left_handed,
            smooth: false,
        }
    }

    #[test]
    fn quads_become_two_triangles_with_the_winding_kept() {
        let m = triangulate(&quad(false, None), |_| {}).unwrap();
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        let m = triangulate(&quad(true, None), |_| {}).unwrap();
        assert_eq!(m.indices, vec![[0, 2, 1], [0, 3, 2]]);
    }

    #[test]
    fn face_varying_and_uniform_normals_follow_the_fan() {
        let fv: Vec<Vec3> = (0..4).map(|i| Vec3::new(i as f32, 0.0, 1.0)).collect();
        let m = triangulate(&quad(false, Some((fv.clone(), "faceVarying".into()))), |_| {}).unwrap();
        assert_eq!(m.normals, Normals::FaceVarying(vec![fv[0], fv[1], fv[2], fv[0], fv[2], fv[3]]));
        let m = triangulate(&quad(false, Some((vec![Vec3::Z], "uniform".into()))), |_| {}).unwrap();
        assert_eq!(m.normals, Normals::FaceVarying(vec![Vec3::Z; 6]));
    }

    #[test]
    fn bad_indices_and_counts_are_errors_naming_the_attribute() {
        let mut q = quad(false, None);
        q.indices[2] = 9;
        assert!(triangulate(&q, |_| {}).unwrap_err().contains("faceVertexIndices[2] = 9"));
        let mut q = quad(false, None);
        q.counts = vec![5];
        assert!(triangulate(&q, |_| {}).unwrap_err().contains("faceVertexCounts"));
    }

    #[test]
    fn wrong_normal_count_is_ignored_with_a_warning() {
        let mut warnings = Vec::new();
        let m = triangulate(&quad(false, Some((vec![Vec3::Z; 3], "vertex".into()))), |w| warnings.push(w)).unwrap();
        assert_eq!(m.normals, Normals::None);
        assert!(warnings[0].contains("3 values for vertex"));
    }
}
