//! Free-flight sampling through heterogeneous volumes: delta tracking for paths (Woodcock et
//! al. 1965; with the emission estimator of Novák et al., "Monte Carlo Methods for Volumetric
//! Light Transport Simulation", Computer Graphics Forum 2018, section 5) and ratio tracking
//! for shadow rays (Novák, Selle & Jarosz, "Residual Ratio Tracking", 2014), each run against
//! the majorant of the grid cell the ray is in.
//!
//! Several volumes along one ray are tracked together: each yields its tentative collisions in
//! order, and the earliest is taken next. The merged stream is the tentative collisions of the
//! summed majorant, and the volume a point came from is chosen with probability σ̄ₖ/Σσ̄, so this
//! is exactly delta tracking through the superposed media.

use glam::Vec3;

use super::Volume;
use super::majorant::Dda;
use crate::geometry::Ray;
use crate::sampling::mix64;

/// Uniform numbers for tracking's unbounded draws, from a seed the path's sampler gives (so
/// renders stay deterministic).
pub struct Stream(u64);

impl Stream {
    /// A stream from `seed`.
    pub fn new(seed: u64) -> Self {
        Stream(mix64(seed ^ 0x7f4a_7c15_9e37_79b9))
    }

    /// The next number in [0, 1).
    #[inline]
    pub fn uniform(&mut self) -> f32 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        (mix64(self.0) >> 40) as f32 * (1.0 / 16_777_216.0)
    }
}

/// One volume's tentative collisions along a ray, nearest first.
struct Tracker<'v> {
    volume: &'v Volume,
    /// The ray in the volume's index space (t stays the world distance).
    o: Vec3,
    d: Vec3,
    cells: Dda,
    /// The current cell and where the ray leaves it.
    cell: Option<(usize, f32)>,
    t: f32,
    /// Raise emitting cells' majorants so their emission is sampled.
    emission: bool,
}

impl<'v> Tracker<'v> {
    fn new(volume: &'v Volume, ray: &Ray, t_max: f32, emission: bool) -> Option<Self> {
        let world_to_index = volume.world_to_index_at(ray.time);
        let (o, d) = (world_to_index.transform_point3(ray.origin), world_to_index.transform_vector3(ray.dir));
        let cells = volume.majorant.walk(o, d, 0.0, t_max)?;
        Some(Tracker { volume, o, d, cells, cell: None, t: 0.0, emission })
    }

    /// The next tentative collision: its t, its majorant and the index-space point.
    fn next(&mut self, s: &mut Stream) -> Option<(f32, f32, Vec3)> {
        loop {
            let (index, exit) = match self.cell {
                Some(c) => c,
                None => {
                    let (index, enter, exit) = self.cells.next()?;
                    self.t = enter;
                    self.cell = Some((index, exit));
                    (index, exit)
                }
            };
            let floor = if self.emission { self.volume.emission_floor } else { 0.0 };
            let sigma = self.volume.majorant.majorant(index, floor);
            if sigma > 0.0 {
                let t = self.t - (1.0 - s.uniform()).ln() / sigma;
                if t < exit {
                    self.t = t;
                    return Some((t, sigma, self.o + self.d * t));
                }
            }
            // Past the cell: sampling starts afresh in the next one (free flight is memoryless).
            self.cell = None;
        }
    }
}

/// Where a path's free flight ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Flight {
    /// Emission gathered along the way (radiance, for the throughput before the flight).
    pub emitted: Vec3,
    /// A real collision: its t and the volume it happened in.
    pub collision: Option<(f32, usize)>,
}

/// Most tentative collisions one ray segment takes: past them the volumes count as opaque
/// there. Extinction so high that a float's steps no longer advance along the ray (a client's
/// 1e30 density) would otherwise loop without end.
pub const MAX_TENTATIVE_COLLISIONS: u32 = 1 << 20;

/// What [`merged`] stopped at.
enum Stop {
    /// The visitor stopped at this collision.
    Visitor,
    /// Every tracker ran out of collisions.
    Exhausted,
    /// [`MAX_TENTATIVE_COLLISIONS`] were taken; the next was at (t, volume).
    TooMany(f32, usize),
}

/// The tentative collisions of every volume along the ray that `include` admits, merged
/// nearest first: `visit` gets each (t, majorant, index-space point, volume) and says whether
/// to go on.
fn merged(
    volumes: &[Volume],
    ray: &Ray,
    t_max: f32,
    emission: bool,
    s: &mut Stream,
    include: impl Fn(usize) -> bool,
    mut visit: impl FnMut(f32, f32, Vec3, usize, &mut Stream) -> bool,
) -> Stop {
    // Each overlapping volume's tracker and its next tentative collision.
    let mut trackers: Vec<(usize, Tracker, (f32, f32, Vec3))> = Vec::new();
    for (k, v) in volumes.iter().enumerate().filter(|&(k, v)| include(k) && v.overlaps(ray, t_max)) {
        let Some(mut tracker) = Tracker::new(v, ray, t_max, emission) else { continue };
        if let Some(first) = tracker.next(s) {
            trackers.push((k, tracker, first));
        }
    }
    for _ in 0..MAX_TENTATIVE_COLLISIONS {
        let Some(i) = (0..trackers.len()).min_by(|&a, &b| trackers[a].2.0.total_cmp(&trackers[b].2.0)) else { return Stop::Exhausted };
        let (k, (t, sigma, p)) = (trackers[i].0, trackers[i].2);
        if !visit(t, sigma, p, k, s) {
            return Stop::Visitor;
        }
        match trackers[i].1.next(s) {
            Some(next) => trackers[i].2 = next,
            None => {
                trackers.swap_remove(i);
            }
        }
    }
    trackers.first().map_or(Stop::TooMany(0.0, 0), |&(k, _, (t, ..))| Stop::TooMany(t, k))
}

/// Delta tracking of a path's ray up to `t_max`: where it first really collides, and the
/// emission it gathers before (each tentative collision adds ε/σ̄).
pub fn fly(volumes: &[Volume], ray: &Ray, t_max: f32, s: &mut Stream) -> Flight {
    let mut flight = Flight { emitted: Vec3::ZERO, collision: None };
    let stop = merged(
        volumes,
        ray,
        t_max,
        true,
        s,
        |_| true,
        |t, sigma, p, k, s| {
            let (extinction, emission) = volumes[k].extinction_and_emission_at(p);
            flight.emitted += emission / sigma;
            if s.uniform() * sigma < extinction {
                flight.collision = Some((t, k));
                return false;
            }
            true
        },
    );
    if let Stop::TooMany(t, k) = stop {
        flight.collision = Some((t, k));
    }
    flight
}

/// Ratio tracking: an unbiased estimate of the transmittance along the ray up to `t_max`
/// through the volumes `casts` admits (a shadow-linked light's), with Russian roulette once it
/// falls below 0.1.
pub fn transmittance(volumes: &[Volume], ray: &Ray, t_max: f32, s: &mut Stream, casts: impl Fn(usize) -> bool) -> f32 {
    let mut tr = 1.0f32;
    let stop = merged(volumes, ray, t_max, false, s, casts, |_, sigma, p, k, s| {
        tr *= 1.0 - (volumes[k].extinction_at(p) / sigma).min(1.0);
        if tr < 0.1 {
            if s.uniform() < 0.5 {
                tr = 0.0;
                return false;
            }
            tr *= 2.0;
        }
        tr > 0.0
    });
    if let Stop::TooMany(..) = stop { 0.0 } else { tr }
}
