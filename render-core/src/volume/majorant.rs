//! The majorant grid: the largest extinction in each block of 8³ voxels, and the cells a ray
//! crosses in order (Amanatides & Woo's DDA, as pbrt-v4's `DDAMajorantIterator` walks its
//! grid), so tracking takes steps sized to the density near the ray rather than to the whole
//! volume's densest voxel.

use glam::{IVec3, UVec3, Vec3};

use super::grid::VoxelGrid;

/// Voxels along each side of a majorant cell: `cargo bench -p tessera --bench volumes`
/// measured 8 fastest on the smoke fixture (docs/benchmarks.md).
pub const CELL: i32 = 8;

/// Per cell: the largest extinction, and whether anything there emits.
#[derive(Clone, Debug)]
pub struct MajorantGrid {
    /// Index-space corner of cell (0, 0, 0).
    lo: Vec3,
    /// Voxels along each side of a cell.
    cell: i32,
    res: UVec3,
    extinction: Vec<f32>,
    emits: Vec<bool>,
}

impl MajorantGrid {
    /// Cells over `support` (index space); `extinction_of` and `emits_in` see each cell's
    /// lattice points as an inclusive index box: every point the trilinear field inside the
    /// cell interpolates from.
    pub fn build(
        support: (Vec3, Vec3),
        cell: i32,
        extinction_of: impl Fn(IVec3, IVec3) -> f32,
        emits_in: impl Fn(IVec3, IVec3) -> bool,
    ) -> Self {
        let (lo, hi) = support;
        let res = ((hi - lo) / cell as f32).ceil().max(Vec3::ONE).as_uvec3();
        let mut extinction = Vec::with_capacity((res.x * res.y * res.z) as usize);
        let mut emits = Vec::with_capacity(extinction.capacity());
        for z in 0..res.z {
            for y in 0..res.y {
                for x in 0..res.x {
                    let c0 = lo.as_ivec3() + IVec3::new(x as i32, y as i32, z as i32) * cell;
                    let (a, b) = (c0, c0 + IVec3::splat(cell));
                    extinction.push(extinction_of(a, b));
                    emits.push(emits_in(a, b));
                }
            }
        }
        MajorantGrid { lo: lo.floor(), cell, res, extinction, emits }
    }

    /// Cells in all.
    pub fn cells(&self) -> usize {
        self.extinction.len()
    }

    /// The cell's extinction majorant, raised to `floor` where it emits (so tracking still
    /// visits emitting cells that do not attenuate).
    #[inline]
    pub fn majorant(&self, cell: usize, floor: f32) -> f32 {
        if self.emits[cell] { self.extinction[cell].max(floor) } else { self.extinction[cell] }
    }

    /// The cells along `o + t d` (index space) for t in `[t0, t1]`.
    pub fn walk(&self, o: Vec3, d: Vec3, t0: f32, t1: f32) -> Option<Dda> {
        let size = self.cell as f32;
        let (lo, hi) = (self.lo, self.lo + self.res.as_vec3() * size);
        let inv = Vec3::ONE / d;
        let (a, b) = ((lo - o) * inv, (hi - o) * inv);
        let enter = a.min(b).max_element().max(t0);
        let exit = a.max(b).min_element().min(t1);
        if !(enter < exit) {
            return None;
        }
        let p = (o + d * enter - lo) / size;
        let cell = p.floor().as_ivec3().clamp(IVec3::ZERO, self.res.as_ivec3() - IVec3::ONE);
        let mut dda =
            Dda { cell, step: IVec3::ZERO, t_next: Vec3::INFINITY, t_delta: Vec3::INFINITY, t: enter, t_end: exit, res: self.res };
        for k in 0..3 {
            if d[k] > 0.0 {
                dda.step[k] = 1;
                dda.t_next[k] = (lo[k] + (cell[k] + 1) as f32 * size - o[k]) / d[k];
                dda.t_delta[k] = size / d[k];
            } else if d[k] < 0.0 {
                dda.step[k] = -1;
                dda.t_next[k] = (lo[k] + cell[k] as f32 * size - o[k]) / d[k];
                dda.t_delta[k] = -size / d[k];
            }
        }
        Some(dda)
    }
}

/// A walk through the majorant grid's cells.
#[derive(Clone, Debug)]
pub struct Dda {
    cell: IVec3,
    step: IVec3,
    t_next: Vec3,
    t_delta: Vec3,
    t: f32,
    t_end: f32,
    res: UVec3,
}

impl Iterator for Dda {
    /// The cell's index and the ray's t on entering and leaving it.
    type Item = (usize, f32, f32);

    fn next(&mut self) -> Option<(usize, f32, f32)> {
        if self.t >= self.t_end {
            return None;
        }
        let r = self.res.as_ivec3();
        let index = (self.cell.x + r.x * (self.cell.y + r.y * self.cell.z)) as usize;
        let axis = if self.t_next.x <= self.t_next.y && self.t_next.x <= self.t_next.z {
            0
        } else if self.t_next.y <= self.t_next.z {
            1
        } else {
            2
        };
        let exit = self.t_next[axis].min(self.t_end);
        let out = (index, self.t, exit);
        self.t = exit;
        self.cell[axis] += self.step[axis];
        self.t_next[axis] += self.t_delta[axis];
        if self.cell[axis] < 0 || self.cell[axis] >= r[axis] {
            self.t = self.t_end;
        }
        Some(out)
    }
}

/// The extinction bound of a cell of `grid` scaled by `scale`.
pub fn grid_max(grid: &VoxelGrid, scale: f32, a: IVec3, b: IVec3) -> f32 {
    grid.max_in(a, b) * scale
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_walk_visits_each_crossed_cell_once_in_order_and_covers_the_segment() {
        let g = MajorantGrid::build((Vec3::ZERO, Vec3::splat(32.0)), CELL, |_, _| 1.0, |_, _| false);
        assert_eq!(g.cells(), 64);
        let (o, d) = (Vec3::new(-5.0, 3.0, 1.0), Vec3::new(1.0, 0.37, 0.11).normalize());
        let cells: Vec<_> = g.walk(o, d, 0.0, 1e9).unwrap().collect();
        for w in cells.windows(2) {
            assert_eq!(w[0].2, w[1].1, "cells abut");
            assert_ne!(w[0].0, w[1].0);
        }
        // Every cell's midpoint lies in that cell.
        for &(c, t0, t1) in &cells {
            let p = (o + d * (0.5 * (t0 + t1))) / 8.0;
            let i = p.floor().as_ivec3();
            assert_eq!(c, (i.x + 4 * (i.y + 4 * i.z)) as usize);
        }
        // Enters at x = 0 and leaves at x = 32 (y and z stay inside).
        assert!((cells[0].1 - 5.0 / d.x).abs() < 1e-4 && (cells.last().unwrap().2 - 37.0 / d.x).abs() < 1e-3);
        // A ray along an axis, and one that misses.
        assert_eq!(g.walk(Vec3::new(4.0, 4.0, -1.0), Vec3::Z, 0.0, 100.0).unwrap().count(), 4);
        assert!(g.walk(Vec3::new(40.0, 4.0, -1.0), Vec3::Z, 0.0, 100.0).is_none());
    }
}
