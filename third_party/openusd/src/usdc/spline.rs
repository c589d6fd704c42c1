//! Attribute splines in binary layers (crate 0.12 and later): the `Ts` binary data a crate
//! stores for a `TsSpline` value, decoded into the dictionary the usda parser builds
//! (`curveType`, `preExtrapolation`, `postExtrapolation`, `loopParameters`, `knots`,
//! `knotCustomData`), so that one evaluator (`usd::spline`) serves both formats.
//!
//! The layout (Pixar's `pxr/base/ts/binary.cpp`, formats 1 to 3; AOUSD Core §16.3.10.33):
//! - header byte: format (bits 0-3), value type (bits 4-5; 4-6 from format 3: 0 untyped,
//!   1 double, 2 float, 3 half), time-valued (bit 6, formats 1-2), Hermite (bit 7);
//! - header byte: pre-extrapolation (bits 0-2), post-extrapolation (bits 3-5), inner loops
//!   (bit 6); format 3 adds a third byte (loop boundary times, unsupported here);
//! - an f64 slope for each sloped extrapolation, then the inner loops' parameters if any;
//! - a u32 knot count and the knots: a flag byte (dual-valued bit 0, next interpolation
//!   bits 1-2, curve type bit 3, Maya-form tangents bits 4-5), f64 time, value, pre-value if
//!   dual-valued, f64 pre and post widths unless Hermite, pre and post slopes, and from
//!   format 2 a byte of tangent algorithms (the tangents they produced are stored anyway).

use std::collections::HashMap;

use anyhow::{Result, bail, ensure};

use crate::gf;
use crate::sdf::Value;

/// Extrapolation modes by their `TsExtrapMode` number.
const EXTRAPOLATIONS: [&str; 7] = ["none", "held", "linear", "sloped", "loopRepeat", "loopReset", "loopOscillate"];

/// Interpolation modes by their `TsInterpMode` number.
const INTERPOLATIONS: [&str; 4] = ["none", "held", "linear", "curve"];

/// A cursor over the spline's bytes; every read is checked against the end.
struct Bytes<'a> {
    data: &'a [u8],
    at: usize,
}

impl Bytes<'_> {
    fn take<const N: usize>(&mut self) -> Result<[u8; N]> {
        let end = self.at.checked_add(N).filter(|&e| e <= self.data.len());
        let Some(end) = end else { bail!("spline data ends early ({} bytes)", self.data.len()) };
        let bytes = self.data[self.at..end].try_into().expect("N bytes");
        self.at = end;
        Ok(bytes)
    }

    fn u8(&mut self) -> Result<u8> {
        Ok(self.take::<1>()?[0])
    }

    fn f64(&mut self) -> Result<f64> {
        Ok(f64::from_le_bytes(self.take()?))
    }

    /// A value of the spline's type, as a double.
    fn value(&mut self, kind: u8) -> Result<f64> {
        Ok(match kind {
            2 => f32::from_le_bytes(self.take()?) as f64,
            3 => gf::f16::from_bits(u16::from_le_bytes(self.take()?)).to_f64(),
            _ => self.f64()?,
        })
    }
}

/// The spline in `Ts` binary data `data`, as the usda parser's dictionary.
pub(super) fn decode(data: &[u8]) -> Result<Value> {
    let mut bytes = Bytes { data, at: 0 };
    let mut spline = HashMap::new();
    spline.insert("knotCustomData".to_owned(), Value::Dictionary(HashMap::new()));
    if data.is_empty() {
        spline.insert("knots".to_owned(), Value::ValueVec(Vec::new()));
        return Ok(Value::Dictionary(spline));
    }
    let header = bytes.u8()?;
    let format = header & 0x0F;
    ensure!((1..=3).contains(&format), "spline data format {format} is not 1, 2 or 3");
    let kind = if format > 2 { (header & 0x70) >> 4 } else { (header & 0x30) >> 4 };
    ensure!(kind <= 3 && (format > 2 || header & 0x40 == 0), "time-valued splines are not supported");
    let hermite = header & 0x80 != 0;
    spline.insert("curveType".to_owned(), Value::token(if hermite { "hermite" } else { "bezier" }));
    let modes = bytes.u8()?;
    let inner_loops = modes & 0x40 != 0;
    if format > 2 {
        ensure!(bytes.u8()? == 0, "spline loop boundary times are not supported");
    }
    for (key, mode) in [("preExtrapolation", modes & 0x07), ("postExtrapolation", (modes & 0x38) >> 3)] {
        let value = extrapolation(&mut bytes, mode)?;
        spline.insert(key.to_owned(), value);
    }
    spline.insert("loopParameters".to_owned(), if inner_loops { loop_parameters(&mut bytes)? } else { Value::ValueBlock });
    let mut knots = Vec::new();
    if kind != 0 || bytes.at < data.len() {
        let count = u32::from_le_bytes(bytes.take()?);
        for _ in 0..count {
            knots.push(knot(&mut bytes, kind, hermite, format)?);
        }
    }
    ensure!(bytes.at == data.len(), "{} bytes after the spline's knots", data.len() - bytes.at);
    spline.insert("knots".to_owned(), Value::ValueVec(knots));
    Ok(Value::Dictionary(spline))
}

fn extrapolation(bytes: &mut Bytes, mode: u8) -> Result<Value> {
    let Some(&name) = EXTRAPOLATIONS.get(mode as usize) else { bail!("unknown spline extrapolation {mode}") };
    if mode == 0 {
        return Ok(Value::ValueBlock);
    }
    let slope = if name == "sloped" { bytes.f64()? } else { 0.0 };
    Ok(Value::Dictionary(HashMap::from([
        ("mode".to_owned(), Value::token(name)),
        ("slope".to_owned(), Value::Double(slope)),
    ])))
}

fn loop_parameters(bytes: &mut Bytes) -> Result<Value> {
    let (start, end) = (bytes.f64()?, bytes.f64()?);
    let (pre, post) = (i32::from_le_bytes(bytes.take()?), i32::from_le_bytes(bytes.take()?));
    Ok(Value::Dictionary(HashMap::from([
        ("protoStart".to_owned(), Value::Double(start)),
        ("protoEnd".to_owned(), Value::Double(end)),
        ("numPreLoops".to_owned(), Value::Double(pre as f64)),
        ("numPostLoops".to_owned(), Value::Double(post as f64)),
        ("valueOffset".to_owned(), Value::Double(bytes.f64()?)),
    ])))
}

fn knot(bytes: &mut Bytes, kind: u8, hermite: bool, format: u8) -> Result<Value> {
    let flags = bytes.u8()?;
    // Maya-form tangents store heights, not slopes; USD itself writes standard ones.
    ensure!(flags & 0x30 == 0, "Maya-form spline tangents are not supported");
    let time = bytes.f64()?;
    let value = bytes.value(kind)?;
    let pre_value = if flags & 0x01 != 0 { bytes.value(kind)? } else { value };
    let (pre_width, post_width) = if hermite { (0.0, 0.0) } else { (bytes.f64()?, bytes.f64()?) };
    let (pre_slope, post_slope) = (bytes.value(kind)?, bytes.value(kind)?);
    if format > 1 {
        bytes.u8()?;
    }
    let next = INTERPOLATIONS[((flags & 0x06) >> 1) as usize];
    Ok(Value::Dictionary(HashMap::from([
        ("time".to_owned(), Value::Double(time)),
        ("value".to_owned(), Value::Double(value)),
        ("preValue".to_owned(), Value::Double(pre_value)),
        ("preTangentSlope".to_owned(), Value::Double(pre_slope)),
        ("preTangentWidth".to_owned(), Value::Double(pre_width)),
        ("postTangentSlope".to_owned(), Value::Double(post_slope)),
        ("postTangentWidth".to_owned(), Value::Double(post_width)),
        ("nextInterpolationMode".to_owned(), Value::token(next)),
    ])))
}
