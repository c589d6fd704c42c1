//! Conversions from `openusd` values to our types, tolerant of the precisions USD allows
//! (half, float, double) for the same role.

use glam::{DMat4, Vec3};
use openusd::sdf::Value;

/// A 3-vector array from any precision.
pub fn vec3_array(v: &Value) -> Option<Vec<Vec3>> {
    Some(match v {
        Value::Vec3fVec(a) => a.iter().map(|p| Vec3::new(p.x, p.y, p.z)).collect(),
        Value::Vec3dVec(a) => a.iter().map(|p| Vec3::new(p.x as f32, p.y as f32, p.z as f32)).collect(),
        Value::Vec3hVec(a) => a.iter().map(|p| Vec3::new(p.x.to_f32(), p.y.to_f32(), p.z.to_f32())).collect(),
        _ => return None,
    })
}

/// An int array (indices, counts) from any integer type.
pub fn int_array(v: &Value) -> Option<Vec<i64>> {
    Some(match v {
        Value::IntVec(a) => a.iter().map(|&x| x as i64).collect(),
        Value::UintVec(a) => a.iter().map(|&x| x as i64).collect(),
        Value::Int64Vec(a) => a.clone(),
        Value::Uint64Vec(a) => a.iter().map(|&x| x as i64).collect(),
        _ => return None,
    })
}

/// A float array from any numeric array type (ints too: `UsdPrimvarReader_int` reads them).
pub fn float_array(v: &Value) -> Option<Vec<f32>> {
    Some(match v {
        Value::FloatVec(a) => a.clone(),
        Value::DoubleVec(a) => a.iter().map(|&x| x as f32).collect(),
        Value::HalfVec(a) => a.iter().map(|x| x.to_f32()).collect(),
        _ => int_array(v)?.into_iter().map(|x| x as f32).collect(),
    })
}

/// A scalar from any numeric type.
pub fn scalar(v: &Value) -> Option<f64> {
    Some(match v {
        Value::Float(x) => *x as f64,
        Value::Double(x) => *x,
        Value::Half(x) => x.to_f64(),
        Value::Int(x) => *x as f64,
        Value::Uint(x) => *x as f64,
        Value::Int64(x) => *x as f64,
        Value::Bool(b) => *b as i32 as f64,
        _ => return None,
    })
}

/// A 3-vector from any precision.
pub fn vec3(v: &Value) -> Option<Vec3> {
    Some(match v {
        Value::Vec3f(p) => Vec3::new(p.x, p.y, p.z),
        Value::Vec3d(p) => Vec3::new(p.x as f32, p.y as f32, p.z as f32),
        Value::Vec3h(p) => Vec3::new(p.x.to_f32(), p.y.to_f32(), p.z.to_f32()),
        _ => return None,
    })
}

/// A 2-vector of doubles from any precision.
pub fn vec2(v: &Value) -> Option<[f64; 2]> {
    Some(match v {
        Value::Vec2f(p) => [p.x as f64, p.y as f64],
        Value::Vec2d(p) => [p.x, p.y],
        Value::Vec2h(p) => [p.x.to_f64(), p.y.to_f64()],
        _ => return None,
    })
}

/// A token or string.
pub fn token(v: &Value) -> Option<String> {
    Some(match v {
        Value::Token(t) => t.as_str().to_string(),
        Value::String(s) => s.clone(),
        _ => return None,
    })
}

/// A token array (or string array).
pub fn token_array(v: &Value) -> Option<Vec<String>> {
    Some(match v {
        Value::TokenVec(t) => t.iter().map(|t| t.as_str().to_string()).collect(),
        Value::StringVec(s) => s.clone(),
        _ => return None,
    })
}

/// A USD matrix (row vectors, translation in the last row) as a glam matrix (column
/// vectors): the same sixteen numbers read as columns are the transpose USD means.
pub fn matrix(m: &openusd::gf::Matrix4d) -> DMat4 {
    DMat4::from_cols_array(&m.0)
}

/// A short description of a value's type, for error messages.
pub fn type_of(v: &Value) -> String {
    let s = format!("{v:?}");
    s.split(['(', ' ', '{']).next().unwrap_or("value").to_string()
}

/// A quaternion array (w, x, y, z) from any precision.
pub fn quat_array(v: &Value) -> Option<Vec<glam::DQuat>> {
    Some(match v {
        Value::QuathVec(a) => a.iter().map(|q| glam::DQuat::from_xyzw(q.x.to_f64(), q.y.to_f64(), q.z.to_f64(), q.w.to_f64())).collect(),
        Value::QuatfVec(a) => a.iter().map(|q| glam::DQuat::from_xyzw(q.x as f64, q.y as f64, q.z as f64, q.w as f64)).collect(),
        Value::QuatdVec(a) => a.iter().map(|q| glam::DQuat::from_xyzw(q.x, q.y, q.z, q.w)).collect(),
        _ => return None,
    })
}

/// A 4-vector from any precision.
pub fn vec4(v: &Value) -> Option<glam::Vec4> {
    Some(match v {
        Value::Vec4f(p) => glam::Vec4::new(p.x, p.y, p.z, p.w),
        Value::Vec4d(p) => glam::Vec4::new(p.x as f32, p.y as f32, p.z as f32, p.w as f32),
        _ => return None,
    })
}

/// A 2-vector array from any precision.
pub fn vec2_array(v: &Value) -> Option<Vec<glam::Vec2>> {
    Some(match v {
        Value::Vec2fVec(a) => a.iter().map(|p| glam::Vec2::new(p.x, p.y)).collect(),
        Value::Vec2dVec(a) => a.iter().map(|p| glam::Vec2::new(p.x as f32, p.y as f32)).collect(),
        Value::Vec2hVec(a) => a.iter().map(|p| glam::Vec2::new(p.x.to_f32(), p.y.to_f32())).collect(),
        _ => return None,
    })
}
