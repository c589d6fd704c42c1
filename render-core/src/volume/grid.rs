//! A voxel grid in index space, as OpenVDB lays it out: the value of voxel (i, j, k) sits at
//! the index-space point (i, j, k), and between lattice points the field is trilinear
//! (OpenVDB's `BoxSampler`), falling to the background 0 one voxel past the last active one.

use glam::{IVec3, UVec3, Vec3};

/// Largest number of voxels one grid may hold (1 GiB of f32).
pub const MAX_VOXELS: u64 = 1 << 28;

/// A dense block of voxels covering a grid's active bounding box.
#[derive(Clone, Debug, PartialEq)]
pub struct VoxelGrid {
    /// Index of the first voxel.
    pub origin: IVec3,
    /// Voxels along x, y and z.
    pub dims: UVec3,
    /// Values, x fastest, then y, then z.
    pub values: Vec<f32>,
}

impl VoxelGrid {
    /// Voxels the grid declares (its dims multiplied, without overflow).
    pub fn voxel_count(dims: UVec3) -> u64 {
        (dims.x as u64).saturating_mul(dims.y as u64).saturating_mul(dims.z as u64)
    }

    /// The value at lattice point `ijk` (0 outside the block).
    #[inline]
    pub fn at(&self, ijk: IVec3) -> f32 {
        let l = ijk - self.origin;
        if l.min_element() < 0 || l.x >= self.dims.x as i32 || l.y >= self.dims.y as i32 || l.z >= self.dims.z as i32 {
            return 0.0;
        }
        self.values[(l.x as usize) + self.dims.x as usize * (l.y as usize + self.dims.y as usize * l.z as usize)]
    }

    /// The trilinear field at index-space point `p`.
    #[inline]
    pub fn sample(&self, p: Vec3) -> f32 {
        let base = p.floor();
        let f = p - base;
        let i = base.as_ivec3();
        let lerp = |a: f32, b: f32, t: f32| a + (b - a) * t;
        let row = |dy: i32, dz: i32| lerp(self.at(i + IVec3::new(0, dy, dz)), self.at(i + IVec3::new(1, dy, dz)), f.x);
        let plane = |dz: i32| lerp(row(0, dz), row(1, dz), f.y);
        lerp(plane(0), plane(1), f.z)
    }

    /// The field at `p` moved into the block first: values at its edge extend outwards (for
    /// fields that qualify another, as a colour does a density, and are undefined outside).
    #[inline]
    pub fn sample_extended(&self, p: Vec3) -> f32 {
        let hi = (self.origin + self.dims.as_ivec3() - IVec3::ONE).as_vec3();
        self.sample(p.clamp(self.origin.as_vec3(), hi.max(self.origin.as_vec3())))
    }

    /// The index-space box where the field may be nonzero: one voxel past the block each way.
    pub fn support(&self) -> (Vec3, Vec3) {
        ((self.origin - IVec3::ONE).as_vec3(), (self.origin + self.dims.as_ivec3()).as_vec3())
    }

    /// The largest value over lattice points in `[lo, hi]` (inclusive, clamped to the block).
    pub fn max_in(&self, lo: IVec3, hi: IVec3) -> f32 {
        let lo = lo.max(self.origin);
        let hi = hi.min(self.origin + self.dims.as_ivec3() - IVec3::ONE);
        let mut m = 0.0f32;
        for z in lo.z..=hi.z {
            for y in lo.y..=hi.y {
                for x in lo.x..=hi.x {
                    m = m.max(self.at(IVec3::new(x, y, z)));
                }
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn trilinear_between_lattice_points_and_zero_past_the_support() {
        let g = VoxelGrid { origin: IVec3::new(-1, 0, 0), dims: UVec3::new(2, 1, 1), values: vec![2.0, 4.0] };
        assert_eq!(g.sample(Vec3::new(-1.0, 0.0, 0.0)), 2.0);
        assert_eq!(g.sample(Vec3::new(-0.5, 0.0, 0.0)), 3.0);
        // Half a voxel past the last active one, half of its value; a whole voxel past, none.
        assert_eq!(g.sample(Vec3::new(0.5, 0.0, 0.0)), 2.0);
        assert_eq!(g.sample(Vec3::new(1.0, 0.0, 0.0)), 0.0);
        assert_eq!(g.sample(Vec3::new(-1.0, 0.5, 0.0)), 1.0);
        assert_eq!(g.max_in(IVec3::splat(-10), IVec3::splat(10)), 4.0);
        assert_eq!(g.support(), (Vec3::new(-2.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0)));
    }
}
