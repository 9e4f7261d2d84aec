//! The bin protocol between the node and its worker processes, in CDR: the node's
//! [`Request`] (who are you, or this bin), the worker's [`Reply`] (who I am, a bin's map, its
//! render). Every float travels as its exact bits, so a worker's map is the one the node's
//! own worker thread would have made; an image whose values are all `k / 255` (every
//! camera image the node decodes) travels as its bytes, a quarter of the floats.
//!
//! This is the project's own protocol between its own processes, not a ROS 2 message: it
//! carries the worker's path (stamps, self-check, Gaussians in the bin frame) rather than a
//! subscriber's view of it. Decoders never panic and never allocate much more than their
//! input (the [`CdrReader`]'s checks, plus the checks of [`WireError::Invalid`]).

use glam::{DAffine3, DMat3, DVec3, Quat, Vec3};
use model::consistency::{CheckReport, Verdict};
use model::frame::{RgbImage, StereoFrame, StereoRig};
use renderer::{GaussianSet, Intrinsics};

use super::fingerprint::Fingerprint;
use crate::msg::{CdrReader, CdrWriter, DecodeError};
use crate::pipeline::self_check::{verdict_code, CheckAction, CheckOutcome, OnCheckFail};
use crate::pipeline::worker::{Output, Rendered, Stamps};

/// The protocol's version: a worker answers a request of another version with an error.
pub const VERSION: u32 = 1;

/// Why a payload is not a valid request or reply.
#[derive(Debug, thiserror::Error)]
pub enum WireError {
    /// The CDR itself is malformed.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// The fields are well-formed CDR but do not make a valid value.
    #[error("`{what}`: {why}")]
    Invalid {
        /// The field.
        what: &'static str,
        /// What is wrong with it.
        why: String,
    },
}

fn invalid(what: &'static str, why: impl Into<String>) -> WireError {
    WireError::Invalid {
        what,
        why: why.into(),
    }
}

/// One bin for a worker process: the node's [`crate::pipeline::worker::Job`] plus what the
/// node asks of the worker.
#[derive(Clone, Debug)]
pub struct BinJob {
    /// The bin.
    pub bin_id: u64,
    /// How many times the node has handed this bin out before (a reassigned bin's late
    /// answer names an older attempt).
    pub attempt: u32,
    /// The reconstructor the node runs: a worker with another refuses the bin.
    pub fingerprint: Fingerprint,
    /// What the worker does with a map failing its self-check.
    pub on_check_fail: OnCheckFail,
    /// Whether the worker renders the map from its input view.
    pub render: bool,
    /// The bin's first frame.
    pub frame: StereoFrame,
    /// The rig the frame was taken with.
    pub rig: StereoRig,
    /// Stamps so far (source, arrival, opened).
    pub stamps: Stamps,
}

impl BinJob {
    /// The payload of `Request::Bin` with this job, made without moving the job (the node
    /// keeps it to check the worker's answer against).
    pub fn request(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        w.u32(VERSION);
        w.u8(REQUEST_BIN);
        write_job(&mut w, self);
        w.into_bytes()
    }
}

/// What the node asks a worker.
#[derive(Clone, Debug)]
pub enum Request {
    /// Who are you: the worker replies [`Reply::Hello`] (or refuses another fingerprint).
    Hello(Fingerprint),
    /// Make this bin's map.
    Bin(Box<BinJob>),
}

/// A worker process's identity, in its answer to [`Request::Hello`].
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Hello {
    /// The reconstructor it runs.
    pub fingerprint: Fingerprint,
    /// Threads its reconstructor uses.
    pub threads: u32,
}

/// What a worker answers.
#[derive(Debug)]
pub enum Reply {
    /// Its identity.
    Hello(Hello),
    /// A bin's map and timings (`Output::point` is 0: a worker runs one point). The
    /// attempt it answers comes first.
    Map(u32, Box<Output>),
    /// The render of the map just sent.
    Render(Rendered),
}

/// What a request asks, as [`Request::kind`] reads it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RequestKind {
    /// [`Request::Hello`].
    Hello,
    /// [`Request::Bin`].
    Bin,
}

/// The bytes [`Request::kind`] reads: the CDR header, the version and the kind.
pub const REQUEST_PREFIX: usize = 9;

const REQUEST_HELLO: u8 = 1;
const REQUEST_BIN: u8 = 2;
const REPLY_HELLO: u8 = 1;
const REPLY_MAP: u8 = 2;
const REPLY_RENDER: u8 = 3;

impl Request {
    /// The payload.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        w.u32(VERSION);
        match self {
            Request::Hello(f) => {
                w.u8(REQUEST_HELLO);
                f.write(&mut w);
            }
            Request::Bin(job) => return job.request(),
        }
        w.into_bytes()
    }

    /// What the request whose payload starts with `prefix` asks, from its first
    /// [`REQUEST_PREFIX`] bytes alone: a busy worker refuses a bin without decoding its
    /// images.
    pub fn kind(prefix: &[u8]) -> Result<RequestKind, WireError> {
        let mut r = CdrReader::new(prefix)?;
        read_version(&mut r)?;
        match r.u8("request kind")? {
            REQUEST_HELLO => Ok(RequestKind::Hello),
            REQUEST_BIN => Ok(RequestKind::Bin),
            other => Err(invalid("request kind", format!("{other} is not 1 or 2"))),
        }
    }

    /// Decodes a payload of [`VERSION`].
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = CdrReader::new(bytes)?;
        read_version(&mut r)?;
        match r.u8("request kind")? {
            REQUEST_HELLO => Ok(Request::Hello(Fingerprint::read(&mut r)?)),
            REQUEST_BIN => Ok(Request::Bin(Box::new(read_job(&mut r)?))),
            other => Err(invalid("request kind", format!("{other} is not 1 or 2"))),
        }
    }
}

impl Reply {
    /// The payload.
    pub fn encode(&self) -> Vec<u8> {
        let mut w = CdrWriter::new();
        w.u32(VERSION);
        match self {
            Reply::Hello(h) => {
                w.u8(REPLY_HELLO);
                h.fingerprint.write(&mut w);
                w.u32(h.threads);
            }
            Reply::Map(attempt, out) => {
                w.u8(REPLY_MAP);
                w.u32(*attempt);
                write_output(&mut w, out);
            }
            Reply::Render(r) => {
                w.u8(REPLY_RENDER);
                w.u64(r.bin_id);
                write_result(&mut w, &r.image, write_image);
                w.i64(r.render_end_ns);
            }
        }
        w.into_bytes()
    }

    /// Decodes a payload of [`VERSION`].
    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        let mut r = CdrReader::new(bytes)?;
        read_version(&mut r)?;
        match r.u8("reply kind")? {
            REPLY_HELLO => Ok(Reply::Hello(Hello {
                fingerprint: Fingerprint::read(&mut r)?,
                threads: r.u32("threads")?,
            })),
            REPLY_MAP => {
                let attempt = r.u32("attempt")?;
                Ok(Reply::Map(attempt, Box::new(read_output(&mut r)?)))
            }
            REPLY_RENDER => Ok(Reply::Render(Rendered {
                bin_id: r.u64("bin_id")?,
                image: read_result(&mut r, read_image)?,
                render_end_ns: r.i64("render_end_ns")?,
            })),
            other => Err(invalid("reply kind", format!("{other} is not 1, 2 or 3"))),
        }
    }
}

fn read_version(r: &mut CdrReader<'_>) -> Result<(), WireError> {
    match r.u32("version")? {
        VERSION => Ok(()),
        other => Err(invalid(
            "version",
            format!("protocol {other}; this build speaks {VERSION}"),
        )),
    }
}

fn write_job(w: &mut CdrWriter, job: &BinJob) {
    w.u64(job.bin_id);
    w.u32(job.attempt);
    job.fingerprint.write(w);
    w.u8(match job.on_check_fail {
        OnCheckFail::Flag => 0,
        OnCheckFail::LowerOpacity => 1,
        OnCheckFail::Sgm => 2,
    });
    w.bool(job.render);
    w.u32(job.frame.index);
    write_image(w, &job.frame.left);
    write_image(w, &job.frame.right);
    write_affine(w, &job.frame.left_to_world);
    let k = &job.rig.intrinsics;
    w.u32(k.width);
    w.u32(k.height);
    w.bytes(&f32_bytes(&[k.fx, k.fy, k.cx, k.cy]));
    w.f64(job.rig.baseline);
    write_stamps(w, &job.stamps);
}

fn read_job(r: &mut CdrReader<'_>) -> Result<BinJob, WireError> {
    let bin_id = r.u64("bin_id")?;
    let attempt = r.u32("attempt")?;
    let fingerprint = Fingerprint::read(r)?;
    let on_check_fail = match r.u8("on_check_fail")? {
        0 => OnCheckFail::Flag,
        1 => OnCheckFail::LowerOpacity,
        2 => OnCheckFail::Sgm,
        other => {
            return Err(invalid(
                "on_check_fail",
                format!("{other} is not 0, 1 or 2"),
            ))
        }
    };
    let render = r.bool("render")?;
    let index = r.u32("frame index")?;
    let left = read_image(r)?;
    let right = read_image(r)?;
    let left_to_world = read_affine(r)?;
    let (width, height) = (r.u32("intrinsics width")?, r.u32("intrinsics height")?);
    let [fx, fy, cx, cy] = read_f32s(r, "intrinsics", 4)?[..] else {
        return Err(invalid("intrinsics", "not 4 values"));
    };
    let baseline = r.f64("baseline")?;
    let stamps = read_stamps(r)?;
    Ok(BinJob {
        bin_id,
        attempt,
        fingerprint,
        on_check_fail,
        render,
        frame: StereoFrame {
            index,
            left,
            right,
            left_to_world,
        },
        rig: StereoRig {
            intrinsics: Intrinsics {
                fx,
                fy,
                cx,
                cy,
                width,
                height,
            },
            baseline,
        },
        stamps,
    })
}

fn write_output(w: &mut CdrWriter, out: &Output) {
    w.u64(out.bin_id);
    write_affine(w, &out.bin_to_world);
    write_result(w, &out.result, write_set);
    write_check(w, &out.check);
    w.bool(out.render_follows);
    write_stamps(w, &out.stamps);
}

fn read_output(r: &mut CdrReader<'_>) -> Result<Output, WireError> {
    Ok(Output {
        bin_id: r.u64("bin_id")?,
        bin_to_world: read_affine(r)?,
        result: read_result(r, read_set)?,
        check: read_check(r)?,
        render_follows: r.bool("render_follows")?,
        stamps: read_stamps(r)?,
        queue_depth: 0,
        point: 0,
    })
}

/// `Ok` as 1 then the value, `Err` as 0 then the message.
fn write_result<T>(w: &mut CdrWriter, v: &Result<T, String>, f: fn(&mut CdrWriter, &T)) {
    match v {
        Ok(x) => {
            w.u8(1);
            f(w, x);
        }
        Err(e) => {
            w.u8(0);
            w.string(e);
        }
    }
}

type ReadFn<T> = fn(&mut CdrReader<'_>) -> Result<T, WireError>;

fn read_result<T>(r: &mut CdrReader<'_>, f: ReadFn<T>) -> Result<Result<T, String>, WireError> {
    match r.u8("result")? {
        1 => Ok(Ok(f(r)?)),
        0 => Ok(Err(r.string("error")?)),
        other => Err(invalid("result", format!("{other} is not 0 or 1"))),
    }
}

fn write_stamps(w: &mut CdrWriter, s: &Stamps) {
    for v in [
        s.source_ns,
        s.arrival_ns,
        s.opened_ns,
        s.model_start_ns,
        s.model_end_ns,
        s.render_end_ns,
        s.publish_ns,
    ]
    .iter()
    .chain(&s.stage_end_ns)
    {
        w.i64(*v);
    }
}

fn read_stamps(r: &mut CdrReader<'_>) -> Result<Stamps, WireError> {
    let mut s = Stamps {
        source_ns: r.i64("source_ns")?,
        arrival_ns: r.i64("arrival_ns")?,
        opened_ns: r.i64("opened_ns")?,
        model_start_ns: r.i64("model_start_ns")?,
        model_end_ns: r.i64("model_end_ns")?,
        render_end_ns: r.i64("render_end_ns")?,
        publish_ns: r.i64("publish_ns")?,
        stage_end_ns: [0; 5],
        // Stamped by the node's outputs after the worker is done.
        map_fused_ns: 0,
    };
    for v in &mut s.stage_end_ns {
        *v = r.i64("stage_end_ns")?;
    }
    Ok(s)
}

fn write_affine(w: &mut CdrWriter, a: &DAffine3) {
    w.f64_array(&a.matrix3.to_cols_array());
    w.f64_array(&a.translation.to_array());
}

fn read_affine(r: &mut CdrReader<'_>) -> Result<DAffine3, WireError> {
    let m: [f64; 9] = r.f64_array("pose rotation")?;
    let t: [f64; 3] = r.f64_array("pose translation")?;
    Ok(DAffine3 {
        matrix3: DMat3::from_cols_array(&m),
        translation: DVec3::from_array(t),
    })
}

/// The 8-bit values of `image` when every float is exactly what
/// [`RgbImage::from_rgb8`] makes of a byte.
fn exact_bytes(image: &RgbImage) -> Option<Vec<u8>> {
    image
        .data
        .iter()
        .map(|&v| {
            let b = (v * 255.0).round();
            let byte = (0.0..=255.0).contains(&b).then_some(b as u8)?;
            (byte as f32 / 255.0 == v).then_some(byte)
        })
        .collect()
}

const IMAGE_BYTES: u8 = 0;
const IMAGE_FLOATS: u8 = 1;

fn write_image(w: &mut CdrWriter, image: &RgbImage) {
    w.u32(image.width);
    w.u32(image.height);
    match exact_bytes(image) {
        Some(bytes) => {
            w.u8(IMAGE_BYTES);
            w.bytes(&bytes);
        }
        None => {
            w.u8(IMAGE_FLOATS);
            w.bytes(&f32_bytes(&image.data));
        }
    }
}

/// `a x b`, or an error naming `what` when the product does not fit a `u64` (a header's
/// sizes are checked before anything is read or allocated by them).
fn times(what: &'static str, a: u64, b: u64) -> Result<u64, WireError> {
    a.checked_mul(b)
        .ok_or_else(|| invalid(what, format!("{a} x {b} does not fit 64 bits")))
}

fn read_image(r: &mut CdrReader<'_>) -> Result<RgbImage, WireError> {
    let (width, height) = (r.u32("image width")?, r.u32("image height")?);
    let values = times("image size", 3 * width as u64, height as u64)?;
    let data = match r.u8("image kind")? {
        IMAGE_BYTES => {
            let bytes = r.bytes("image bytes")?;
            if bytes.len() as u64 != values {
                return Err(invalid(
                    "image bytes",
                    format!("{} for a {width}x{height} image", bytes.len()),
                ));
            }
            return Ok(RgbImage::from_rgb8(width, height, &bytes));
        }
        IMAGE_FLOATS => read_f32s(r, "image floats", values)?,
        other => return Err(invalid("image kind", format!("{other} is not 0 or 1"))),
    };
    Ok(RgbImage {
        width,
        height,
        data,
    })
}

fn f32_bytes(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// `count` little-endian floats from a `uint8[]` sequence holding exactly them.
fn read_f32s(r: &mut CdrReader<'_>, what: &'static str, count: u64) -> Result<Vec<f32>, WireError> {
    let want = times(what, 4, count)?;
    let bytes = r.bytes(what)?;
    if bytes.len() as u64 != want {
        return Err(invalid(
            what,
            format!("{} bytes for {count} floats", bytes.len()),
        ));
    }
    Ok(bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect())
}

fn write_set(w: &mut CdrWriter, set: &GaussianSet) {
    let vec3 = |v: &[Vec3]| f32_bytes(&v.iter().flat_map(|x| x.to_array()).collect::<Vec<_>>());
    w.u32(set.len() as u32);
    w.bytes(&vec3(&set.means));
    w.bytes(&vec3(&set.log_scales));
    let quats: Vec<f32> = set.rotations.iter().flat_map(|q| q.to_array()).collect();
    w.bytes(&f32_bytes(&quats));
    w.bytes(&f32_bytes(&set.opacities));
    w.bytes(&vec3(&set.colors));
    w.bytes(&f32_bytes(&set.confidences));
}

fn read_set(r: &mut CdrReader<'_>) -> Result<GaussianSet, WireError> {
    let n = r.u32("gaussians")? as u64;
    let vec3 = |r: &mut CdrReader<'_>, what| -> Result<Vec<Vec3>, WireError> {
        Ok(read_f32s(r, what, times(what, 3, n)?)?
            .chunks_exact(3)
            .map(Vec3::from_slice)
            .collect())
    };
    let means = vec3(r, "means")?;
    let log_scales = vec3(r, "log_scales")?;
    let rotations = read_f32s(r, "rotations", times("rotations", 4, n)?)?
        .chunks_exact(4)
        .map(Quat::from_slice)
        .collect();
    let opacities = read_f32s(r, "opacities", n)?;
    let colors = vec3(r, "colors")?;
    let confidences = read_f32s(r, "confidences", n)?;
    Ok(GaussianSet {
        means,
        log_scales,
        rotations,
        opacities,
        colors,
        confidences,
    })
}

fn write_report(w: &mut CdrWriter, report: Option<&CheckReport>) {
    w.u8(verdict_code(report));
    if let Some(c) = report {
        w.bytes(&f32_bytes(&[c.score, c.coverage]));
        w.u32(c.samples);
        w.u32(c.textured);
    }
}

fn read_report(r: &mut CdrReader<'_>) -> Result<Option<CheckReport>, WireError> {
    let verdict = match r.u8("verdict")? {
        0 => return Ok(None),
        1 => Verdict::Pass,
        2 => Verdict::Fail,
        3 => Verdict::Undetermined,
        other => return Err(invalid("verdict", format!("{other} is not 0 to 3"))),
    };
    let [score, coverage] = read_f32s(r, "check score", 2)?[..] else {
        return Err(invalid("check score", "not 2 values"));
    };
    Ok(Some(CheckReport {
        score,
        coverage,
        samples: r.u32("check samples")?,
        textured: r.u32("check textured")?,
        verdict,
    }))
}

fn write_check(w: &mut CdrWriter, c: &CheckOutcome) {
    write_report(w, c.primary.as_ref());
    w.u8(c.action.code());
    write_report(w, c.fallback.as_ref());
}

fn read_check(r: &mut CdrReader<'_>) -> Result<CheckOutcome, WireError> {
    let primary = read_report(r)?;
    let action = match r.u8("check action")? {
        0 => CheckAction::None,
        1 => CheckAction::Flagged,
        2 => CheckAction::LoweredOpacity,
        3 => CheckAction::Sgm,
        other => return Err(invalid("check action", format!("{other} is not 0 to 3"))),
    };
    Ok(CheckOutcome {
        primary,
        action,
        fallback: read_report(r)?,
    })
}

#[cfg(test)]
#[path = "wire_tests.rs"]
mod tests;
