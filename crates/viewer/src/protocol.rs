//! The messages of the WebSocket protocol: parsing the client's, writing the server's.

use fibfluid_geometry::Vec3;
use fibfluid_interact::FrameGuardError;
use fibfluid_interact::{LinearizationStatus, ToolLoad};
use fibfluid_sim::result_guards::ResultWarning;
use serde_json::Value;

/// A client message.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ClientMessage {
    /// `{"grab": V, "to": [x, y, z]}`: hold file vertex `V` at the position `to`.
    Grab {
        /// Vertex in the file's order.
        vertex: usize,
        /// Target position (world coordinates, not a displacement).
        to: Vec3,
    },
    /// `{"release": V}`: drop the hold on `V`.
    Release {
        /// Vertex in the file's order.
        vertex: usize,
    },
    /// `{"grasp": V, "radius": r, "to": [x, y, z]}`: hold the patch of every vertex within
    /// `r` (rest positions, Euclidean) of file vertex `V`, moved rigidly so that `V` is at
    /// `to`. `{"release": V}` drops it.
    Grasp {
        /// The picked vertex in the file's order.
        vertex: usize,
        /// The patch radius (the mesh's coordinates).
        radius: f64,
        /// Target position of the picked vertex.
        to: Vec3,
    },
    /// `{"press": [x, y, z], "radius": r}`: the spherical tip of radius `r` centred at
    /// `[x, y, z]` (one tip per connection; a later press moves it).
    Press {
        /// Centre of the tip.
        centre: Vec3,
        /// Radius of the tip.
        radius: f64,
    },
    /// `{"lift": true}`: take the tip away.
    Lift,
    /// `{"reset": true}`: drop every hold, grasp and the tip.
    Reset,
}

/// Why a client message was refused (sent back as `{"error": "..."}`).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum MessageError {
    /// Not JSON, or not one of the protocol's messages.
    #[error("malformed message: {problem}")]
    Malformed {
        /// What is wrong.
        problem: String,
    },
    /// A target with a NaN, infinite or null component.
    #[error("vertex {vertex}: the target position has a non-finite component ({value})")]
    NonFinite {
        /// The vertex.
        vertex: usize,
        /// The component as sent.
        value: String,
    },
    /// A tip centre with a NaN, infinite or null component.
    #[error("the tip's centre has a non-finite component ({value})")]
    NonFiniteCentre {
        /// The component as sent.
        value: String,
    },
    /// A vertex beyond the mesh.
    #[error("vertex {vertex} does not exist (the mesh has {count} vertices, 0-based)")]
    UnknownVertex {
        /// The vertex.
        vertex: usize,
        /// Vertices of the mesh.
        count: usize,
    },
    /// A vertex of the file that no face uses.
    #[error("vertex {vertex} is not used by any face of the mesh")]
    UnusedVertex {
        /// The vertex.
        vertex: usize,
    },
    /// A grab of a vertex the scene fixes.
    #[error("vertex {vertex} is fixed by the scene; it cannot be grabbed")]
    FixedVertex {
        /// The vertex.
        vertex: usize,
    },
    /// A binary message from the client.
    #[error("binary messages are not part of the protocol (send JSON text)")]
    Binary,
    /// The body refused the request or could not compute the frame.
    #[error("{0}")]
    Body(#[from] fibfluid_interact::InteractError),
    /// The frame cannot be checked: its answer is not finite (the vertex in the file's
    /// order), so nothing is shown.
    #[error("{0}; the frame is not shown (release or reset)")]
    Answer(#[from] FrameGuardError),
}

fn malformed(problem: impl Into<String>) -> MessageError {
    MessageError::Malformed { problem: problem.into() }
}

const EXPECTED: &str = r#"expected {"grab": V, "to": [x, y, z]}, {"grasp": V, "radius": r, "to": [x, y, z]}, {"press": [x, y, z], "radius": r}, {"release": V}, {"lift": true} or {"reset": true}"#;

fn vertex_of(v: &Value, key: &str) -> Result<usize, MessageError> {
    match v.as_u64() {
        Some(i) => usize::try_from(i).map_err(|_| malformed(format!("`{key}`: vertex {i} is too large"))),
        None => Err(malformed(format!("`{key}` must be a vertex index (0, 1, 2, ...), found {v}"))),
    }
}

fn sorted<'a>(keys: &[&'a str]) -> Vec<&'a str> {
    let mut k = keys.to_vec();
    k.sort_unstable();
    k
}

/// A point `[x, y, z]` of finite numbers; `non_finite` makes the error of a NaN, infinite
/// or null component from the component as sent.
fn point_of(v: &Value, key: &str, non_finite: impl Fn(String) -> MessageError) -> Result<Vec3, MessageError> {
    let Some(arr) = v.as_array().filter(|a| a.len() == 3) else {
        return Err(malformed(format!("`{key}` must be [x, y, z], found {v}")));
    };
    let mut to = [0.0; 3];
    for (c, x) in arr.iter().enumerate() {
        to[c] = match x {
            Value::Number(n) => {
                n.as_f64().ok_or_else(|| malformed(format!("`{key}`: {n} is not a number")))?
            }
            // JavaScript's JSON.stringify writes NaN and infinities as null.
            Value::Null => f64::NAN,
            Value::String(s) => match s.trim().to_ascii_lowercase().as_str() {
                "nan" | "inf" | "+inf" | "-inf" | "infinity" | "+infinity" | "-infinity" => f64::NAN,
                _ => return Err(malformed(format!("`{key}`: \"{s}\" is not a number"))),
            },
            other => return Err(malformed(format!("`{key}`: {other} is not a number"))),
        };
        if !to[c].is_finite() {
            return Err(non_finite(x.to_string()));
        }
    }
    Ok(to)
}

/// A tool radius: a positive finite number.
fn radius_of(v: &Value) -> Result<f64, MessageError> {
    match v.as_f64() {
        Some(r) if r > 0.0 && r.is_finite() => Ok(r),
        _ => Err(malformed(format!("`radius` must be a positive number, found {v}"))),
    }
}

/// Parses one text message. Vertices are checked against the mesh by the caller.
pub fn parse_message(text: &str) -> Result<ClientMessage, MessageError> {
    let value: Value = serde_json::from_str(text).map_err(|e| malformed(format!("not JSON ({e})")))?;
    let Value::Object(obj) = value else {
        return Err(malformed(format!("not a JSON object; {EXPECTED}")));
    };
    let keys: Vec<&str> = obj.keys().map(String::as_str).collect();
    match keys.as_slice() {
        ["grab", "to"] | ["to", "grab"] => {
            let vertex = vertex_of(&obj["grab"], "grab")?;
            let to = point_of(&obj["to"], "to", |value| MessageError::NonFinite { vertex, value })?;
            Ok(ClientMessage::Grab { vertex, to })
        }
        _ if sorted(&keys) == ["grasp", "radius", "to"] => {
            let vertex = vertex_of(&obj["grasp"], "grasp")?;
            let to = point_of(&obj["to"], "to", |value| MessageError::NonFinite { vertex, value })?;
            Ok(ClientMessage::Grasp { vertex, radius: radius_of(&obj["radius"])?, to })
        }
        _ if sorted(&keys) == ["press", "radius"] => {
            let centre = point_of(&obj["press"], "press", |value| MessageError::NonFiniteCentre { value })?;
            Ok(ClientMessage::Press { centre, radius: radius_of(&obj["radius"])? })
        }
        ["lift"] => match obj["lift"] {
            Value::Bool(true) => Ok(ClientMessage::Lift),
            ref other => Err(malformed(format!("`lift` must be true, found {other}"))),
        },
        ["release"] => Ok(ClientMessage::Release { vertex: vertex_of(&obj["release"], "release")? }),
        ["reset"] => match obj["reset"] {
            Value::Bool(true) => Ok(ClientMessage::Reset),
            ref other => Err(malformed(format!("`reset` must be true, found {other}"))),
        },
        _ => Err(malformed(format!("unknown keys {keys:?}; {EXPECTED}"))),
    }
}

/// The text message of a frame: `{"frame": k, "reactions": [[V, fx, fy, fz], ...],
/// "latency_us": t, "warnings": [...]}` (reactions by file vertex, ascending; the result
/// guards that fired on the frame, each `{"guard": name, "value": v, "limit": l,
/// "message": text}`, empty when none did), plus `"tools": [...]` when a grasp or the tip is
/// active (see [`ToolLoad`]), plus `"linearization": {"refreshes", "age_frames",
/// "age_ms", "refresh_ms", "estimated_error", "pending", "failure"}` on a two-rate body
/// (the neo-Hookean FEM: the linearization the frame used, its age, the last refresh's
/// time, the frame's estimated distance from the converged answer, m, and the held
/// vertices it left free while their columns are made).
pub fn frame_json(
    frame: u64,
    reactions: &[(usize, Vec3)],
    latency_us: f64,
    tools: &[ToolLoad],
    warnings: &[ResultWarning],
    linearization: Option<&LinearizationStatus>,
) -> String {
    let r: Vec<Value> = reactions.iter().map(|&(v, f)| serde_json::json!([v, f[0], f[1], f[2]])).collect();
    let w: Vec<Value> = warnings
        .iter()
        .map(|w| {
            serde_json::json!({
                "guard": w.guard.to_string(),
                "value": w.value,
                "limit": w.limit,
                "message": w.to_string(),
            })
        })
        .collect();
    let mut msg =
        serde_json::json!({ "frame": frame, "reactions": r, "latency_us": latency_us, "warnings": w });
    if !tools.is_empty() {
        msg["tools"] = serde_json::to_value(tools).unwrap_or(Value::Null);
    }
    if let Some(s) = linearization {
        msg["linearization"] = serde_json::json!({
            "refreshes": s.refreshes,
            "refactorizations": s.refactorizations,
            "age_frames": s.age_frames,
            "age_ms": (s.age_seconds * 1e4).round() / 10.0,
            "refresh_ms": (s.refresh_seconds * 1e4).round() / 10.0,
            "estimated_error": s.estimated_error,
            "pending": s.pending,
            "failure": s.failure,
        });
    }
    msg.to_string()
}

/// The binary message of a frame: `3 N` little-endian `f32` positions (`x0 y0 z0 x1 ...`).
pub fn positions_le_f32(positions: &[Vec3], out: &mut Vec<u8>) {
    out.clear();
    out.reserve(12 * positions.len());
    for p in positions {
        for c in p {
            out.extend_from_slice(&(*c as f32).to_le_bytes());
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_the_three_messages() {
        assert_eq!(
            parse_message(r#"{"grab": 3, "to": [1, 2.5, -1e-3]}"#),
            Ok(ClientMessage::Grab { vertex: 3, to: [1.0, 2.5, -1e-3] })
        );
        assert_eq!(parse_message(r#"{"release": 7}"#), Ok(ClientMessage::Release { vertex: 7 }));
        assert_eq!(parse_message(r#"{"reset": true}"#), Ok(ClientMessage::Reset));
    }

    #[test]
    fn refuses_bad_messages() {
        for bad in [
            "grab 3",
            "[1, 2]",
            r#"{"grab": -1, "to": [0, 0, 0]}"#,
            r#"{"grab": 1.5, "to": [0, 0, 0]}"#,
            r#"{"grab": 1, "to": [0, 0]}"#,
            r#"{"grab": 1}"#,
            r#"{"reset": false}"#,
            r#"{"release": 1, "reset": true}"#,
            r#"{"grab": 1, "to": [0, "a", 0]}"#,
        ] {
            assert!(matches!(parse_message(bad), Err(MessageError::Malformed { .. })), "{bad}");
        }
        for nonfinite in [r#"{"grab": 2, "to": [null, 0, 0]}"#, r#"{"grab": 2, "to": [0, "NaN", 0]}"#] {
            assert!(matches!(parse_message(nonfinite), Err(MessageError::NonFinite { vertex: 2, .. })));
        }
    }

    #[test]
    fn positions_are_little_endian_f32() {
        let mut out = Vec::new();
        positions_le_f32(&[[1.0, -2.0, 0.5]], &mut out);
        assert_eq!(out, [0, 0, 128, 63, 0, 0, 0, 192, 0, 0, 0, 63]);
    }
}
