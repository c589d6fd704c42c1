//! `UsdGeomMesh` to triangles: polygon fan triangulation, winding, and normals in every
//! interpolation the slice supports.

use glam::Vec2;
use glam::Vec3;
use render_core::geometry::{Attribute, Mesh, Normals, Primvar, Uvs};

/// Authored mesh data, straight from the stage.
#[derive(Clone)]
pub struct MeshSource {
    /// `points`.
    pub points: Vec<Vec3>,
    /// `faceVertexCounts`.
    pub counts: Vec<i64>,
    /// `faceVertexIndices`.
    pub indices: Vec<i64>,
    /// `normals` (or `primvars:normals`, de-indexed) and their interpolation.
    pub normals: Option<(Vec<Vec3>, String)>,
    /// A float2 primvar for texture coordinates: its name, values (de-indexed) and interpolation.
    pub uvs: Option<(String, Vec<Vec2>, String)>,
    /// Other primvars the materials read by name (float and int in x, float3 in xyz): name
    /// without `primvars:`, values (de-indexed) and interpolation.
    pub primvars: Vec<(String, Vec<Vec3>, String)>,
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
/// mesh of its own: same points (and deformation), the kept triangles, their normals.
pub fn select_faces(mesh: &Mesh, face_of: &[u32], keep: impl Fn(u32) -> bool) -> Mesh {
    let kept: Vec<usize> = (0..mesh.indices.len()).filter(|&t| keep(face_of[t])).collect();
    fn keep_corners<T: Copy>(a: &Attribute<T>, kept: &[usize]) -> Attribute<T> {
        match a {
            Attribute::FaceVarying(n) => {
                Attribute::FaceVarying(kept.iter().flat_map(|&t| [n[3 * t], n[3 * t + 1], n[3 * t + 2]]).collect())
            }
            other => other.clone(),
        }
    }
    Mesh {
        positions: mesh.positions.clone(),
        indices: kept.iter().map(|&t| mesh.indices[t]).collect(),
        normals: keep_corners(&mesh.normals, &kept),
        uvs: keep_corners(&mesh.uvs, &kept),
        primvars: mesh.primvars.iter().map(|p| Primvar { name: p.name.clone(), values: keep_corners(&p.values, &kept) }).collect(),
        deformation: mesh.deformation.clone(),
    }
}

/// The only faults [`triangulate_with_faces`] cannot render: face-vertex counts that do not
/// add up to the face-vertex indices, or an index out of range for the points.
pub fn check_faces(src: &MeshSource) -> Result<(), String> {
    let total: i64 = src.counts.iter().sum();
    if src.counts.iter().any(|&c| c < 0) || total != src.indices.len() as i64 {
        return Err(format!("faceVertexCounts add up to {total} but faceVertexIndices has {} entries", src.indices.len()));
    }
    let n = src.points.len() as i64;
    if let Some((i, &v)) = src.indices.iter().enumerate().find(|&(_, &v)| v < 0 || v >= n) {
        return Err(format!("faceVertexIndices[{i}] = {v} is out of range for {n} points"));
    }
    Ok(())
}

/// [`triangulate`], also returning the authored face of each triangle.
pub fn triangulate_with_faces(src: &MeshSource, mut warn: impl FnMut(String)) -> Result<(Mesh, Vec<u32>), String> {
    check_faces(src)?;
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
        let polygon: Vec<Vec3> = (0..count).map(|k| src.points[src.indices[base + k] as usize]).collect();
        for [a, b, c] in polygon_triangles(&polygon) {
            let c = if src.left_handed { [base + a, base + c, base + b] } else { [base + a, base + b, base + c] };
            tris.push(c.map(|i| src.indices[i] as u32));
            corners.push(c);
            uniform_of.push(face);
        }
        base += count;
    }
    if degenerate_faces > 0 {
        warn(format!("{degenerate_faces} face(s) with fewer than 3 vertices skipped"));
    }

    let layout = Layout { points: src.points.len(), faces: src.counts.len(), corners: &corners, face_of: &uniform_of };
    let normals = match &src.normals {
        None if src.smooth => Normals::Vertex(smooth_normals(&src.points, &tris)),
        None => Normals::None,
        Some((n, interp)) => layout.expand("normals", n, interp, &mut warn),
    };
    let uvs = match &src.uvs {
        None => Uvs::None,
        Some((name, uv, interp)) => layout.expand(name, uv, interp, &mut warn),
    };
    let primvars = src
        .primvars
        .iter()
        .map(|(name, v, interp)| Primvar { name: name.clone(), values: layout.expand(&format!("primvars:{name}"), v, interp, &mut warn) })
        .filter(|p| !p.values.is_empty())
        .collect();
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
    Ok((Mesh { positions: src.points.clone(), indices: tris, normals, uvs, primvars, deformation: Vec::new() }, face_of))
}

/// How many values each primvar interpolation takes on a mesh.
pub(super) struct Sizes {
    pub points: usize,
    pub face_vertices: usize,
    pub faces: usize,
}

impl Sizes {
    /// Whether `len` values fit `interp`; when not (or the interpolation is unknown), a
    /// warning naming the primvar. A face-varying primvar may cover more face-vertices than
    /// the faces use.
    pub(super) fn fits(&self, name: &str, len: usize, interp: &str, warn: &mut impl FnMut(String)) -> bool {
        let want = match interp {
            "vertex" | "varying" => self.points,
            "faceVarying" => self.face_vertices,
            "uniform" => self.faces,
            "constant" => 1,
            other => {
                warn(format!("{name}: unknown interpolation '{other}'; ignoring it"));
                return false;
            }
        };
        let fits = if interp == "faceVarying" { len >= want } else { len == want };
        if !fits {
            warn(format!("{name}: {len} values for {interp} interpolation, {want} expected; ignoring them"));
        }
        fits
    }
}

/// Where each triangle corner came from, to lay out primvars of any interpolation.
struct Layout<'a> {
    points: usize,
    faces: usize,
    /// Authored face-vertex index of each triangle corner.
    corners: &'a [[usize; 3]],
    /// Authored face of each triangle.
    face_of: &'a [usize],
}

impl Layout<'_> {
    /// A primvar of `interp` interpolation (already de-indexed) on the triangles; a length
    /// that does not match its interpolation is a warning naming the primvar, and it is ignored.
    fn expand<T: Copy>(&self, name: &str, v: &[T], interp: &str, warn: &mut impl FnMut(String)) -> Attribute<T> {
        let face_vertices: usize = self.corners.iter().flatten().max().map_or(0, |m| m + 1);
        let sizes = Sizes { points: self.points, face_vertices, faces: self.faces };
        if !sizes.fits(name, v.len(), interp, warn) {
            return Attribute::None;
        }
        match interp {
            "vertex" | "varying" => Attribute::Vertex(v.to_vec()),
            "faceVarying" => Attribute::FaceVarying(self.corners.iter().flat_map(|c| c.map(|i| v[i])).collect()),
            "uniform" => Attribute::FaceVarying(self.face_of.iter().flat_map(|&f| [v[f]; 3]).collect()),
            _ => Attribute::FaceVarying(vec![v[0]; 3 * self.corners.len()]),
        }
    }
}

/// Triangles (corner indices into `polygon`) covering a planar polygon: a fan when it is
/// convex, ear clipping in the polygon's own plane (Newell's normal) when it is not, so that
/// concave n-gons (an L, a star) do not get triangles outside their outline. A polygon ear
/// clipping cannot finish (self-intersecting, degenerate) falls back to the fan.
fn polygon_triangles(polygon: &[Vec3]) -> Vec<[usize; 3]> {
    let n = polygon.len();
    let fan = || (1..n.saturating_sub(1)).map(|k| [0, k, k + 1]).collect::<Vec<_>>();
    if n <= 3 {
        return fan();
    }
    // Newell's normal: robust for any planar (or nearly planar) polygon.
    let mut normal = Vec3::ZERO;
    for i in 0..n {
        let (p, q) = (polygon[i], polygon[(i + 1) % n]);
        normal += Vec3::new((p.y - q.y) * (p.z + q.z), (p.z - q.z) * (p.x + q.x), (p.x - q.x) * (p.y + q.y));
    }
    let Some(normal) = normal.try_normalize() else { return fan() };
    let turn = |a: Vec3, b: Vec3, c: Vec3| (b - a).cross(c - b).dot(normal);
    if (0..n).all(|i| turn(polygon[i], polygon[(i + 1) % n], polygon[(i + 2) % n]) >= 0.0) {
        return fan();
    }
    // Inside or on the boundary: a reflex vertex on an ear's edge blocks it too.
    let inside = |p: Vec3, a: Vec3, b: Vec3, c: Vec3| {
        p != a
            && p != b
            && p != c
            && (b - a).cross(p - a).dot(normal) >= 0.0
            && (c - b).cross(p - b).dot(normal) >= 0.0
            && (a - c).cross(p - c).dot(normal) >= 0.0
    };
    let mut left: Vec<usize> = (0..n).collect();
    let mut out = Vec::with_capacity(n - 2);
    let mut guard = 0;
    while left.len() > 3 {
        let m = left.len();
        let ear = (0..m).find(|&i| {
            let (a, b, c) = (left[(i + m - 1) % m], left[i], left[(i + 1) % m]);
            turn(polygon[a], polygon[b], polygon[c]) > 0.0
                && !left.iter().any(|&k| k != a && k != b && k != c && inside(polygon[k], polygon[a], polygon[b], polygon[c]))
        });
        let Some(i) = ear else { return fan() };
        out.push([left[(i + m - 1) % m], left[i], left[(i + 1) % m]]);
        left.remove(i);
        guard += 1;
        if guard > n {
            return fan();
        }
    }
    out.push([left[0], left[1], left[2]]);
    out
}

/// Area-weighted vertex normals.
fn smooth_normals(points: &[Vec3], tris: &[[u32; 3]]) -> Vec<Vec3> {
    render_core::geometry::area_weighted_normals(points, tris, |v| v as usize, points.len())
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
            uvs: None,
            primvars: Vec::new(),
            left_handed,
            smooth: false,
        }
    }

    #[test]
    fn concave_ngons_are_ear_clipped_inside_their_outline() {
        // An L-shaped hexagon: a fan from vertex 0 would put a triangle across the notch.
        let l = [(0.0, 0.0), (2.0, 0.0), (2.0, 1.0), (1.0, 1.0), (1.0, 2.0), (0.0, 2.0)];
        let points: Vec<Vec3> = l.iter().map(|&(x, y)| Vec3::new(x, y, 0.0)).collect();
        let src = MeshSource {
            points: points.clone(),
            counts: vec![6],
            indices: (0..6).collect(),
            normals: None,
            uvs: None,
            primvars: Vec::new(),
            left_handed: false,
            smooth: false,
        };
        let m = triangulate(&src, |_| {}).unwrap();
        assert_eq!(m.indices.len(), 4);
        let mut area = 0.0;
        for t in &m.indices {
            let [a, b, c] = t.map(|i| points[i as usize]);
            let signed = 0.5 * (b - a).cross(c - a).z;
            assert!(signed > 0.0, "every triangle keeps the winding: {t:?}");
            // No triangle covers the notch's centre (1.5, 1.5).
            let centroid = (a + b + c) / 3.0;
            assert!(!(centroid.x > 1.0 && centroid.y > 1.0), "a triangle in the notch: {t:?}");
            area += signed;
        }
        assert!((area - 3.0).abs() < 1e-6, "the triangles cover the L exactly: {area}");
        // Convex polygons keep the fan.
        assert_eq!(polygon_triangles(&points[..4]).len(), 2);
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
