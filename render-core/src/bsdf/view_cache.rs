//! One value of a lobe that depends only on the view direction, kept from [`super::Bsdf::prepare`]
//! to the evaluations and samples that follow at the same shading point.
//!
//! A path vertex evaluates its BSDF for next-event estimation, samples it, and evaluates it
//! again for the sample's weight and density, always with the same `wo`. Energy-compensated
//! lobes read E(μo) from a table each time (bilinear, trilinear or, for anisotropic GGX,
//! quadrilinear); the cache turns the repeats into one comparison. A lobe used without
//! `prepare` (tests, the lobe benchmark) or with another `wo` looks the value up as before, so
//! the values are the same to the bit either way.

use glam::Vec3;

/// The value at the last `wo` a lobe was prepared for. Lobes fill it in `prepare`, never
/// when built: a lobe that is built but never shaded (weight 0, say) must not build tables.
#[derive(Clone, Copy, Debug)]
pub struct ViewCache<T> {
    wo: Vec3,
    value: T,
}

impl<T: Default> Default for ViewCache<T> {
    /// Empty: NaN equals no direction.
    fn default() -> Self {
        ViewCache { wo: Vec3::NAN, value: T::default() }
    }
}

/// A cache is not part of what a lobe is: two lobes with equal parameters are equal.
impl<T> PartialEq for ViewCache<T> {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

impl<T: Copy> ViewCache<T> {
    /// Remembers `value` as the value at `wo`.
    #[inline]
    pub fn store(&mut self, wo: Vec3, value: T) {
        *self = ViewCache { wo, value };
    }

    /// The value at `wo`: the stored one when `wo` is the direction it was stored for,
    /// otherwise `compute()`.
    #[inline(always)]
    pub fn get(&self, wo: Vec3, compute: impl FnOnce() -> T) -> T {
        if wo == self.wo { self.value } else { compute() }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_stored_value_is_read_only_at_its_own_direction() {
        let mut c = ViewCache::<f32>::default();
        let wo = Vec3::new(0.0, 0.6, 0.8);
        assert_eq!(c.get(wo, || 2.0), 2.0, "empty: computed");
        c.store(wo, 1.0);
        assert_eq!(c.get(wo, || 2.0), 1.0);
        assert_eq!(c.get(Vec3::new(0.0, 0.0, 1.0), || 2.0), 2.0, "another direction: computed");
        assert_eq!(ViewCache::default(), c, "caches never make lobes differ");
    }
}
