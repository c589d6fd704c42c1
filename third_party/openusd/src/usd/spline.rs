//! Evaluation of attribute splines (`.spline`, USD 25.05; pxr's `Ts` library), from the
//! dictionary the usda parser stores: knots with held, linear or Bézier (or Hermite) segments,
//! dual values, and held, linear, sloped, looping or blocked extrapolation.
//!
//! Inner loops (`loop: (...)`, deprecated in `Ts`) are not evaluated: such a spline reads as
//! unauthored here.

use std::collections::HashMap;

use crate::sdf::Value;

/// True when `value` (a `spline` field's) is a spline that value resolution evaluates; false
/// for one it passes over (inner loops, unknown modes, or not a parsed spline at all).
pub fn evaluates(value: &Value) -> bool {
    Spline::from_value(value).is_some()
}

/// A spline's value at one time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) enum Sample {
    /// The value.
    Value(f64),
    /// A value block: no value at this time (a blocked segment or extrapolation).
    Block,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Interp {
    Held,
    Linear,
    Curve,
    Block,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Extrap {
    Held,
    Linear,
    Sloped(f64),
    Repeat,
    Reset,
    Oscillate,
    Block,
}

#[derive(Clone, Copy, Debug)]
struct Knot {
    time: f64,
    value: f64,
    /// The value approached from the left: `value` unless the knot is dual-valued.
    pre_value: f64,
    pre_slope: f64,
    pre_width: f64,
    post_slope: f64,
    post_width: f64,
    next: Interp,
}

/// A spline ready to evaluate.
#[derive(Debug)]
pub(crate) struct Spline {
    knots: Vec<Knot>,
    hermite: bool,
    pre: Extrap,
    post: Extrap,
}

impl Spline {
    /// The spline in a `spline` field's value; `None` when it is not one this evaluates.
    pub(crate) fn from_value(value: &Value) -> Option<Spline> {
        let Value::Dictionary(d) = value else { return None };
        if !matches!(d.get("loopParameters"), None | Some(Value::ValueBlock)) {
            return None;
        }
        let Some(Value::ValueVec(knots)) = d.get("knots") else { return None };
        let mut knots = knots.iter().map(knot).collect::<Option<Vec<Knot>>>()?;
        knots.sort_by(|a, b| a.time.total_cmp(&b.time));
        let hermite = matches!(d.get("curveType"), Some(Value::Token(t)) if t.as_str() == "hermite");
        Some(Spline { knots, hermite, pre: extrapolation(d.get("preExtrapolation"))?, post: extrapolation(d.get("postExtrapolation"))? })
    }

    /// The value at `time`; `None` for a spline without knots.
    pub(crate) fn at(&self, time: f64) -> Option<Sample> {
        let (first, last) = (self.knots.first()?, self.knots.last()?);
        if time < first.time {
            return Some(self.extrapolate(time, self.pre, true));
        }
        // The last knot's own time belongs to what follows it: the next cycle of a loop, or
        // a blocked extrapolation.
        if time >= last.time {
            return Some(self.extrapolate(time, self.post, false));
        }
        Some(self.inside(time, false))
    }

    /// The value at a time within the knots' span; `from_left` takes the limit from earlier
    /// times where `time` is a knot's (a mirrored cycle runs backwards through its knots).
    fn inside(&self, time: f64, from_left: bool) -> Sample {
        // The knot that starts the segment `time` is in.
        let i = match from_left {
            false => self.knots.partition_point(|k| k.time <= time),
            true => self.knots.partition_point(|k| k.time < time),
        }
        .saturating_sub(1);
        let k0 = &self.knots[i];
        let Some(k1) = self.knots.get(i + 1).filter(|_| time > k0.time) else {
            return Sample::Value(if from_left { k0.pre_value } else { k0.value });
        };
        match k0.next {
            Interp::Held => Sample::Value(k0.value),
            Interp::Linear => Sample::Value(k0.value + (k1.pre_value - k0.value) * (time - k0.time) / (k1.time - k0.time)),
            Interp::Curve => Sample::Value(self.bezier(k0, k1, time)),
            Interp::Block => Sample::Block,
        }
    }

    /// The curved segment from `k0` to `k1` at `time`: a cubic Bézier whose inner control
    /// points lie along the knots' tangents, at their widths (a third of the segment each
    /// for Hermite splines). Widths that overlap are scaled down together to fit the segment
    /// (`Ts`'s "keep ratio" rule), so time stays monotonic along the curve.
    fn bezier(&self, k0: &Knot, k1: &Knot, time: f64) -> f64 {
        let span = k1.time - k0.time;
        let (mut w0, mut w1) = if self.hermite { (span / 3.0, span / 3.0) } else { (k0.post_width, k1.pre_width) };
        let fit = non_regressive_scale(w0 / span, w1 / span);
        (w0, w1) = (w0 * fit, w1 * fit);
        let xs = [k0.time, k0.time + w0, k1.time - w1, k1.time];
        let ys = [k0.value, k0.value + k0.post_slope * w0, k1.pre_value - k1.pre_slope * w1, k1.pre_value];
        cubic(&ys, parameter_at(&xs, time))
    }

    /// The value beyond the knots, `before` the first or after the last.
    fn extrapolate(&self, time: f64, mode: Extrap, before: bool) -> Sample {
        let (first, last) = (self.knots[0], self.knots[self.knots.len() - 1]);
        let (edge, from) = if before { (first.pre_value, first.time) } else { (last.value, last.time) };
        let period = last.time - first.time;
        let lines = |slope: f64| Sample::Value(edge + slope * (time - from));
        match mode {
            Extrap::Block => Sample::Block,
            Extrap::Held => Sample::Value(edge),
            Extrap::Sloped(slope) => lines(slope),
            Extrap::Linear => lines(self.edge_slope(before)),
            _ if period <= 0.0 => Sample::Value(edge),
            Extrap::Repeat | Extrap::Reset | Extrap::Oscillate => {
                let cycles = ((time - first.time) / period).floor();
                let mut local = time - cycles * period;
                let mirrored = mode == Extrap::Oscillate && cycles.rem_euclid(2.0) == 1.0;
                if mirrored {
                    local = first.time + last.time - local;
                }
                // Each repeat is shifted by the rise from the first knot to the last: their
                // values after the knots, or before them for the repeats before the knots.
                let rise = if before { last.pre_value - first.pre_value } else { last.value - first.value };
                let offset = if mode == Extrap::Repeat { cycles * rise } else { 0.0 };
                match self.inside(local.clamp(first.time, last.time), mirrored) {
                    Sample::Value(v) => Sample::Value(v + offset),
                    Sample::Block => Sample::Block,
                }
            }
        }
    }

    /// The slope linear extrapolation continues at the first knot (`before`) or the last:
    /// the adjacent segment's (a held one is flat, a curved one leaves along the knot's
    /// tangent); flat for a single knot.
    fn edge_slope(&self, before: bool) -> f64 {
        let n = self.knots.len();
        if n < 2 {
            return 0.0;
        }
        let (k0, k1) = if before { (&self.knots[0], &self.knots[1]) } else { (&self.knots[n - 2], &self.knots[n - 1]) };
        // A dual-valued knot at the edge jumps there: the extrapolation stays flat.
        let edge = if before { k0 } else { k1 };
        if edge.pre_value != edge.value {
            return 0.0;
        }
        match k0.next {
            Interp::Held | Interp::Block => 0.0,
            Interp::Linear => (k1.pre_value - k0.value) / (k1.time - k0.time),
            // Along the knot's tangent, whatever its width (zero included).
            Interp::Curve if before => k0.post_slope,
            Interp::Curve => k1.pre_slope,
        }
    }
}

/// The factor (at most 1) that scales tangent widths `a` and `b` (as fractions of their
/// segment) so that time never runs backwards along the curve. The curve's time derivative is
/// 3[(1-u)²a + 2u(1-u)(1-a-b) + u²b], which stays non-negative on [0, 1] when a + b ≤ 1 or
/// (1-a-b)² ≤ ab; on the boundary, scaled by k, k = 1/(a + b - √(ab)). Both widths shrink by
/// the same factor, `Ts`'s "keep ratio" rule.
fn non_regressive_scale(a: f64, b: f64) -> f64 {
    if a + b <= 1.0 || (1.0 - a - b).powi(2) <= a * b {
        return 1.0;
    }
    (1.0 / (a + b - (a * b).sqrt())).min(1.0)
}

/// The parameter in [0, 1] at which the Bézier with control abscissae `xs` (non-decreasing)
/// reaches `x`, by bisection: 60 halvings reach the resolution of an f64.
fn parameter_at(xs: &[f64; 4], x: f64) -> f64 {
    let (mut lo, mut hi) = (0.0, 1.0);
    for _ in 0..60 {
        let mid = 0.5 * (lo + hi);
        if cubic(xs, mid) < x {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// The cubic Bézier of control values `p` at parameter `u`.
fn cubic(p: &[f64; 4], u: f64) -> f64 {
    let v = 1.0 - u;
    v * v * v * p[0] + 3.0 * v * v * u * p[1] + 3.0 * v * u * u * p[2] + u * u * u * p[3]
}

fn knot(value: &Value) -> Option<Knot> {
    let Value::Dictionary(k) = value else { return None };
    let num = |key: &str| match k.get(key) {
        Some(Value::Double(x)) if x.is_finite() => Some(*x),
        _ => None,
    };
    let next = match k.get("nextInterpolationMode") {
        Some(Value::Token(t)) => match t.as_str() {
            "held" => Interp::Held,
            "linear" => Interp::Linear,
            "curve" => Interp::Curve,
            "none" => Interp::Block,
            _ => return None,
        },
        _ => Interp::Held,
    };
    let value = num("value")?;
    Some(Knot {
        time: num("time")?,
        value,
        pre_value: num("preValue").unwrap_or(value),
        pre_slope: num("preTangentSlope").unwrap_or(0.0),
        pre_width: num("preTangentWidth").unwrap_or(0.0).max(0.0),
        post_slope: num("postTangentSlope").unwrap_or(0.0),
        post_width: num("postTangentWidth").unwrap_or(0.0).max(0.0),
        next,
    })
}

fn extrapolation(value: Option<&Value>) -> Option<Extrap> {
    let d: &HashMap<String, Value> = match value {
        None => return Some(Extrap::Held),
        Some(Value::ValueBlock) => return Some(Extrap::Block),
        Some(Value::Dictionary(d)) => d,
        Some(_) => return None,
    };
    let slope = match d.get("slope") {
        Some(Value::Double(s)) if s.is_finite() => *s,
        _ => 0.0,
    };
    Some(match d.get("mode") {
        Some(Value::Token(t)) => match t.as_str() {
            "held" => Extrap::Held,
            "linear" => Extrap::Linear,
            "sloped" => Extrap::Sloped(slope),
            "loopRepeat" => Extrap::Repeat,
            "loopReset" => Extrap::Reset,
            "loopOscillate" => Extrap::Oscillate,
            _ => return None,
        },
        _ => return None,
    })
}
