//! Gaussian sets as binary glTF 2.0 (`.glb`) with the Khronos extension
//! `KHR_gaussian_splatting` (KhronosGroup/glTF, `extensions/2.0/Khronos/KHR_gaussian_splatting`),
//! which Babylon.js, CesiumJS and splat-transform read.
//!
//! One node, one mesh, one primitive in `POINTS` mode carrying the extension (`kernel`
//! `ellipse`, `colorSpace` `srgb_rec709_display`: 3DGS colours are display values, as the
//! renderer's are; `sortingMethod` `cameraDistance`, `projection` `perspective`) and these
//! attributes, one per Gaussian, each in its own tightly packed buffer view:
//!
//! | attribute | accessor | value |
//! | --- | --- | --- |
//! | `POSITION` | VEC3 float, with `min`/`max` | centre, metres |
//! | `COLOR_0` | VEC4 unsigned byte, normalized | colour clamped to [0, 1], opacity (the fallback for viewers without the extension) |
//! | `KHR_gaussian_splatting:ROTATION` | VEC4 float | unit quaternion (x, y, z, w) |
//! | `KHR_gaussian_splatting:SCALE` | VEC3 float | standard deviations, linear (the ratified draft; not the log of the PLY files) |
//! | `KHR_gaussian_splatting:OPACITY` | SCALAR float | opacity in [0, 1] (after the sigmoid) |
//! | `KHR_gaussian_splatting:SH_DEGREE_0_COEF_0` | VEC3 float | SH DC, `(colour - 0.5) / SH_C0`, colour clamped to [0, 1] |
//! | `_CONFIDENCE` | SCALAR float | the renderer's confidence (an application attribute; others ignore it) |
//!
//! Axes: glTF is right-handed with +Y up and cameras looking down -Z; the renderer's frames
//! are RDF (x right, y down, z forward), so positions and rotations are written in RUB, y and
//! z negated ([`super::to_exchange_frame`]): a glTF camera at the origin with no rotation
//! sees what the renderer's identity camera sees. Positions stay float32, as the set's are:
//! the format adds no error (at 1e5 m from the frame's origin float32 itself resolves 7.8 mm,
//! which is why the node exports maps around their latest bin, not the world origin).
//! An empty set is a scene with no mesh (glTF accessors cannot be empty).
//!
//! The reader reads such files back: float accessors without sparse storage or interleaving,
//! from the GLB's own binary chunk (no external or data-URI buffers); anything else is a typed
//! error, and it never panics.

use std::io::{self, Read, Write};

use glam::{Quat, Vec3};
use serde_json::{json, Value};

use super::{
    from_exchange_frame, rotation_from_exchange, rotation_to_exchange, to_exchange_frame,
    unit_rotation,
};
use crate::gaussians::{Gaussian, GaussianSet, LengthMismatch};
use crate::ply::SH_C0;

/// The GLB header's magic, "glTF" little endian.
pub const MAGIC: u32 = 0x4654_6c67;
/// The extension's name.
pub const EXTENSION: &str = "KHR_gaussian_splatting";
const CHUNK_JSON: u32 = 0x4e4f_534a;
const CHUNK_BIN: u32 = 0x004e_4942;
const FLOAT: u32 = 5126;
const UNSIGNED_BYTE: u32 = 5121;
/// The largest JSON chunk the reader accepts, bytes.
const MAX_JSON_BYTES: u32 = 64 << 20;

/// Everything that can go wrong writing or reading a `.glb`.
#[derive(Debug, thiserror::Error)]
pub enum GlbError {
    /// The underlying reader or writer failed.
    #[error("glTF I/O error")]
    Io(#[from] io::Error),
    /// The file does not start with the GLB header of glTF 2.0.
    #[error("not a binary glTF 2.0 file: {0}")]
    NotGlb(String),
    /// The JSON chunk does not parse.
    #[error("the glTF JSON chunk does not parse")]
    Json(#[source] serde_json::Error),
    /// The document is glTF but not Gaussians this reader takes.
    #[error("glTF: {0}")]
    Unsupported(String),
    /// A value the writer cannot store (a non-finite number).
    #[error("Gaussian {index}: {what} is not finite; glTF cannot hold it")]
    NonFinite {
        /// The Gaussian's index in the set.
        index: usize,
        /// The field.
        what: &'static str,
    },
    /// The set to write has arrays of different lengths.
    #[error(transparent)]
    LengthMismatch(#[from] LengthMismatch),
    /// The set or the file is larger than a GLB can address (4 GiB).
    #[error("{0} too large for a GLB (4 GiB at most)")]
    TooLarge(&'static str),
}

/// Writes `set` as a `.glb` with `KHR_gaussian_splatting` (see the module documentation).
/// Colours and opacities are clamped to [0, 1]; a non-finite value, or a scale whose
/// exponential is not finite, is refused ([`GlbError::NonFinite`]).
pub fn write_glb(set: &GaussianSet, mut w: impl Write) -> Result<(), GlbError> {
    set.check_lengths()?;
    let n = set.len();
    let mut position = Vec::with_capacity(n * 12);
    let mut colour = Vec::with_capacity(n * 4);
    let mut rotation = Vec::with_capacity(n * 16);
    let mut scale = Vec::with_capacity(n * 12);
    let mut opacity = Vec::with_capacity(n * 4);
    let mut sh0 = Vec::with_capacity(n * 12);
    let mut confidence = Vec::with_capacity(n * 4);
    let (mut lo, mut hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
    let floats =
        |out: &mut Vec<u8>, vs: &[f32]| vs.iter().for_each(|v| out.extend(v.to_le_bytes()));
    for i in 0..n {
        let g = set.get(i);
        let sigma = g.log_scale.exp();
        let checks = [
            ("position", g.mean.is_finite()),
            ("scale", sigma.is_finite()),
            ("rotation", g.rotation.is_finite()),
            ("opacity", g.opacity.is_finite()),
            ("colour", g.color.is_finite()),
            ("confidence", g.confidence.is_finite()),
        ];
        if let Some((what, _)) = checks.iter().find(|(_, ok)| !ok) {
            return Err(GlbError::NonFinite { index: i, what });
        }
        let p = to_exchange_frame(g.mean);
        (lo, hi) = (lo.min(p), hi.max(p));
        let c = g.color.clamp(Vec3::ZERO, Vec3::ONE);
        let a = g.opacity.clamp(0.0, 1.0);
        floats(&mut position, &p.to_array());
        colour.extend((c.extend(a).to_array()).map(|v| (v * 255.0).round() as u8));
        floats(
            &mut rotation,
            &rotation_to_exchange(unit_rotation(g.rotation)).to_array(),
        );
        floats(&mut scale, &sigma.to_array());
        floats(&mut opacity, &[a]);
        let dc = (c.as_dvec3() - 0.5) / SH_C0;
        floats(&mut sh0, &dc.as_vec3().to_array());
        floats(&mut confidence, &[g.confidence]);
    }

    // The document is built with serde_json's `json!`, already a dependency: the glTF crates
    // (gltf-json) would add a dependency tree for a dozen fixed fields, and neither knows
    // this extension's attribute names or properties better than the draft this follows.
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": "stereosplat"},
        "extensionsUsed": [EXTENSION],
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"name": "gaussians"}],
    });
    let mut bin = Vec::new();
    if n > 0 {
        let count = u32::try_from(n).map_err(|_| GlbError::TooLarge("the set"))?;
        let views = [
            ("POSITION", "VEC3", FLOAT, position),
            ("COLOR_0", "VEC4", UNSIGNED_BYTE, colour),
            ("KHR_gaussian_splatting:ROTATION", "VEC4", FLOAT, rotation),
            ("KHR_gaussian_splatting:SCALE", "VEC3", FLOAT, scale),
            ("KHR_gaussian_splatting:OPACITY", "SCALAR", FLOAT, opacity),
            (
                "KHR_gaussian_splatting:SH_DEGREE_0_COEF_0",
                "VEC3",
                FLOAT,
                sh0,
            ),
            ("_CONFIDENCE", "SCALAR", FLOAT, confidence),
        ];
        let (mut attributes, mut buffer_views, mut accessors) =
            (serde_json::Map::new(), Vec::new(), Vec::new());
        for (i, (name, kind, component, bytes)) in views.into_iter().enumerate() {
            buffer_views.push(json!({
                "buffer": 0, "byteOffset": bin.len(), "byteLength": bytes.len(),
            }));
            let mut accessor = json!({
                "bufferView": i, "componentType": component, "count": count, "type": kind,
            });
            if component == UNSIGNED_BYTE {
                accessor["normalized"] = json!(true);
            }
            if name == "POSITION" {
                accessor["min"] = json!(lo.to_array());
                accessor["max"] = json!(hi.to_array());
            }
            accessors.push(accessor);
            attributes.insert(name.to_owned(), json!(i));
            bin.extend_from_slice(&bytes);
            bin.resize(bin.len().next_multiple_of(4), 0);
        }
        doc["nodes"][0]["mesh"] = json!(0);
        doc["meshes"] = json!([{"primitives": [{
            "mode": 0,
            "attributes": attributes,
            "extensions": {EXTENSION: {
                "kernel": "ellipse",
                "colorSpace": "srgb_rec709_display",
                "sortingMethod": "cameraDistance",
                "projection": "perspective",
            }},
        }]}]);
        doc["buffers"] = json!([{"byteLength": bin.len()}]);
        doc["bufferViews"] = json!(buffer_views);
        doc["accessors"] = json!(accessors);
    }
    let mut text = serde_json::to_vec(&doc).map_err(GlbError::Json)?;
    text.resize(text.len().next_multiple_of(4), b' ');
    let bin_chunk = if bin.is_empty() { 0 } else { 8 + bin.len() };
    let total = u32::try_from(12 + 8 + text.len() + bin_chunk)
        .map_err(|_| GlbError::TooLarge("the set"))?;
    w.write_all(&MAGIC.to_le_bytes())?;
    w.write_all(&2u32.to_le_bytes())?;
    w.write_all(&total.to_le_bytes())?;
    w.write_all(&(text.len() as u32).to_le_bytes())?;
    w.write_all(&CHUNK_JSON.to_le_bytes())?;
    w.write_all(&text)?;
    if !bin.is_empty() {
        w.write_all(&(bin.len() as u32).to_le_bytes())?;
        w.write_all(&CHUNK_BIN.to_le_bytes())?;
        w.write_all(&bin)?;
    }
    w.flush()?;
    Ok(())
}

/// Reads a `.glb` of Gaussians (see the module documentation for what is taken): every
/// primitive with `KHR_gaussian_splatting` of every mesh, in order.
pub fn read_glb(mut r: impl Read) -> Result<GaussianSet, GlbError> {
    let mut header = [0u8; 12];
    r.read_exact(&mut header)
        .map_err(|_| GlbError::NotGlb("shorter than the 12-byte header".into()))?;
    let word = |b: &[u8], i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
    if word(&header, 0) != MAGIC {
        return Err(GlbError::NotGlb("no `glTF` magic".into()));
    }
    if word(&header, 4) != 2 {
        return Err(GlbError::NotGlb(format!(
            "version {}, 2 expected",
            word(&header, 4)
        )));
    }
    let total = u64::from(word(&header, 8));
    // The chunks, read no further than the declared length and grown only as data arrives.
    let mut body = Vec::new();
    r.take(total.saturating_sub(12)).read_to_end(&mut body)?;
    let chunk = |at: usize| -> Option<(u32, &[u8])> {
        let head = body.get(at..at.checked_add(8)?)?;
        let len = word(head, 0) as usize;
        Some((word(head, 4), body.get(at + 8..(at + 8).checked_add(len)?)?))
    };
    let (kind, json_bytes) =
        chunk(0).ok_or_else(|| GlbError::NotGlb("truncated JSON chunk".into()))?;
    if kind != CHUNK_JSON || json_bytes.len() > MAX_JSON_BYTES as usize {
        return Err(GlbError::NotGlb(
            "the first chunk is not a JSON chunk".into(),
        ));
    }
    let doc: Value = serde_json::from_slice(json_bytes).map_err(GlbError::Json)?;
    let bin = match chunk(8 + json_bytes.len()) {
        Some((CHUNK_BIN, b)) => b,
        _ => &[],
    };
    let mut set = GaussianSet::default();
    for mesh in doc["meshes"].as_array().map_or(&[][..], |v| v) {
        for prim in mesh["primitives"].as_array().map_or(&[][..], |v| v) {
            if prim["extensions"].get(EXTENSION).is_some() {
                read_primitive(&doc, bin, prim, &mut set)?;
            }
        }
    }
    Ok(set)
}

/// Appends the Gaussians of one primitive.
fn read_primitive(
    doc: &Value,
    bin: &[u8],
    prim: &Value,
    set: &mut GaussianSet,
) -> Result<(), GlbError> {
    let attr = |name: &str, k: usize, required: bool| -> Result<Option<Vec<f32>>, GlbError> {
        match prim["attributes"].get(name).and_then(Value::as_u64) {
            Some(i) => float_accessor(doc, bin, i, k).map(Some),
            None if required => Err(GlbError::Unsupported(format!("no `{name}` attribute"))),
            None => Ok(None),
        }
    };
    let p = attr("POSITION", 3, true)?.unwrap_or_default();
    let q = attr("KHR_gaussian_splatting:ROTATION", 4, true)?.unwrap_or_default();
    let s = attr("KHR_gaussian_splatting:SCALE", 3, true)?.unwrap_or_default();
    let a = attr("KHR_gaussian_splatting:OPACITY", 1, true)?.unwrap_or_default();
    let dc = attr("KHR_gaussian_splatting:SH_DEGREE_0_COEF_0", 3, true)?.unwrap_or_default();
    let conf = attr("_CONFIDENCE", 1, false)?;
    let n = p.len() / 3;
    if [q.len() / 4, s.len() / 3, a.len(), dc.len() / 3] != [n; 4]
        || conf.as_ref().is_some_and(|c| c.len() != n)
    {
        return Err(GlbError::Unsupported(
            "attributes of different counts".into(),
        ));
    }
    for i in 0..n {
        let v3 = |v: &[f32]| Vec3::new(v[3 * i], v[3 * i + 1], v[3 * i + 2]);
        let rot = Quat::from_xyzw(q[4 * i], q[4 * i + 1], q[4 * i + 2], q[4 * i + 3]);
        let colour = (0.5 + SH_C0 * v3(&dc).as_dvec3()).as_vec3();
        set.push(Gaussian {
            mean: from_exchange_frame(v3(&p)),
            // Linear scales; zero or negative ones (invalid) become the smallest positive.
            log_scale: v3(&s).max(Vec3::splat(f32::MIN_POSITIVE)).ln(),
            rotation: unit_rotation(rotation_from_exchange(rot)),
            opacity: a[i],
            color: colour,
            confidence: conf.as_ref().map_or(1.0, |c| c[i]),
        });
    }
    Ok(())
}

/// The values of accessor `index`, which must be `k` floats per element, stored tightly in
/// a buffer view of the binary chunk.
fn float_accessor(doc: &Value, bin: &[u8], index: u64, k: usize) -> Result<Vec<f32>, GlbError> {
    let bad = |what: String| GlbError::Unsupported(format!("accessor {index}: {what}"));
    let acc = doc["accessors"]
        .get(index as usize)
        .ok_or_else(|| bad("missing".into()))?;
    let want_type = ["", "SCALAR", "", "VEC3", "VEC4"][k];
    if acc["componentType"].as_u64() != Some(u64::from(FLOAT)) || acc["type"] != want_type {
        return Err(bad(format!("not {want_type} float")));
    }
    if acc.get("sparse").is_some() {
        return Err(bad("sparse storage is not read here".into()));
    }
    let count = acc["count"]
        .as_u64()
        .ok_or_else(|| bad("no count".into()))?;
    let view_index = acc["bufferView"]
        .as_u64()
        .ok_or_else(|| bad("no buffer view".into()))?;
    let view = doc["bufferViews"]
        .get(view_index as usize)
        .ok_or_else(|| bad("missing buffer view".into()))?;
    if view["buffer"].as_u64() != Some(0) {
        return Err(bad("data outside the GLB's binary chunk".into()));
    }
    let stride = view["byteStride"].as_u64().unwrap_or(4 * k as u64);
    if stride != 4 * k as u64 {
        return Err(bad("interleaved data is not read here".into()));
    }
    let start = view["byteOffset"].as_u64().unwrap_or(0) + acc["byteOffset"].as_u64().unwrap_or(0);
    let len = count
        .checked_mul(stride)
        .ok_or_else(|| bad("too large".into()))?;
    let view_len = view["byteLength"].as_u64().unwrap_or(0);
    let end = start
        .checked_add(len)
        .ok_or_else(|| bad("too large".into()))?;
    let view_end = view["byteOffset"]
        .as_u64()
        .unwrap_or(0)
        .saturating_add(view_len);
    if end > view_end || end > bin.len() as u64 {
        return Err(bad(format!(
            "bytes {start}..{end} outside its view or the {} bytes of data",
            bin.len()
        )));
    }
    Ok(bin[start as usize..end as usize]
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect())
}
