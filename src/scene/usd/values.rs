//! Conversions from USD attribute values (`sdf::Value`) to numbers, tokens and vectors.

use crate::math::{Vec2, Vec3, Vec4};
use openusd::sdf;

/// A number from any scalar numeric value.
pub(super) fn number(v: &sdf::Value) -> Option<f64> {
    match v {
        sdf::Value::Float(x) => Some(*x as f64),
        sdf::Value::Double(x) => Some(*x),
        sdf::Value::Half(x) => Some(x.to_f64()),
        sdf::Value::Int(x) => Some(*x as f64),
        sdf::Value::Int64(x) => Some(*x as f64),
        sdf::Value::Uint(x) => Some(*x as f64),
        sdf::Value::Bool(b) => Some(*b as u8 as f64),
        _ => None,
    }
}

/// A token or string.
pub(super) fn token(v: &sdf::Value) -> Option<String> {
    match v {
        sdf::Value::Token(t) => Some(t.as_str().to_owned()),
        sdf::Value::String(s) => Some(s.clone()),
        _ => None,
    }
}

pub(super) fn tokens(v: &sdf::Value) -> Option<Vec<String>> {
    match v {
        sdf::Value::TokenVec(t) => Some(t.iter().map(|t| t.as_str().to_owned()).collect()),
        sdf::Value::StringVec(s) => Some(s.clone()),
        _ => None,
    }
}

pub(super) fn vec3(v: &sdf::Value) -> Option<Vec3> {
    match v {
        sdf::Value::Vec3f(a) => Some(Vec3::new(a.x, a.y, a.z)),
        sdf::Value::Vec3d(a) => Some(Vec3::new(a.x as f32, a.y as f32, a.z as f32)),
        sdf::Value::Vec3h(a) => Some(Vec3::new(a.x.to_f32(), a.y.to_f32(), a.z.to_f32())),
        _ => None,
    }
}

/// A four-component vector (`float4`, `double4`, `half4`).
pub(super) fn vec4(v: &sdf::Value) -> Option<Vec4> {
    match v {
        sdf::Value::Vec4f(a) => Some(Vec4::new(a.x, a.y, a.z, a.w)),
        sdf::Value::Vec4d(a) => Some(Vec4::new(a.x as f32, a.y as f32, a.z as f32, a.w as f32)),
        sdf::Value::Vec4h(a) => Some(Vec4::new(
            a.x.to_f32(),
            a.y.to_f32(),
            a.z.to_f32(),
            a.w.to_f32(),
        )),
        _ => None,
    }
}

pub(super) fn vec3_array(v: &sdf::Value) -> Option<Vec<Vec3>> {
    match v {
        sdf::Value::Vec3fVec(a) => Some(a.iter().map(|a| Vec3::new(a.x, a.y, a.z)).collect()),
        sdf::Value::Vec3dVec(a) => Some(
            a.iter()
                .map(|a| Vec3::new(a.x as f32, a.y as f32, a.z as f32))
                .collect(),
        ),
        sdf::Value::Vec3hVec(a) => Some(
            a.iter()
                .map(|a| Vec3::new(a.x.to_f32(), a.y.to_f32(), a.z.to_f32()))
                .collect(),
        ),
        _ => None,
    }
}

pub(super) fn vec2_array(v: &sdf::Value) -> Option<Vec<Vec2>> {
    match v {
        sdf::Value::Vec2fVec(a) => Some(a.iter().map(|a| Vec2::new(a.x, a.y)).collect()),
        sdf::Value::Vec2dVec(a) => Some(
            a.iter()
                .map(|a| Vec2::new(a.x as f32, a.y as f32))
                .collect(),
        ),
        sdf::Value::Vec2hVec(a) => Some(
            a.iter()
                .map(|a| Vec2::new(a.x.to_f32(), a.y.to_f32()))
                .collect(),
        ),
        _ => None,
    }
}

/// A 2-vector (`float2`, `double2`, `half2`).
pub(super) fn vec2(v: &sdf::Value) -> Option<Vec2> {
    match v {
        sdf::Value::Vec2f(a) => Some(Vec2::new(a.x, a.y)),
        sdf::Value::Vec2d(a) => Some(Vec2::new(a.x as f32, a.y as f32)),
        sdf::Value::Vec2h(a) => Some(Vec2::new(a.x.to_f32(), a.y.to_f32())),
        _ => None,
    }
}
