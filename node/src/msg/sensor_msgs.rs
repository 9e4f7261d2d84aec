//! `sensor_msgs`: Image, CompressedImage, CameraInfo (with RegionOfInterest) and
//! PointCloud2 (with PointField), field for field as the ROS 2 Jazzy `.msg` definitions.

use super::cdr::{CdrReader, CdrWriter, DecodeError};
use super::std_msgs::Header;
use super::{Message, MessageKind};

/// `sensor_msgs/msg/Image`: an uncompressed image, rows of `step` bytes.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Image {
    /// Capture time and the camera's optical frame.
    pub header: Header,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Pixel encoding (`rgb8`, `bgr8`, `mono8`, ...).
    pub encoding: String,
    /// 1 when multi-byte channels are big endian.
    pub is_bigendian: u8,
    /// Bytes per row.
    pub step: u32,
    /// `step * height` bytes.
    pub data: Vec<u8>,
}

impl Message for Image {
    const KIND: MessageKind = MessageKind::Image;

    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.u32(self.height);
        w.u32(self.width);
        w.string(&self.encoding);
        w.u8(self.is_bigendian);
        w.u32(self.step);
        w.bytes(&self.data);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(r)?,
            height: r.u32("height")?,
            width: r.u32("width")?,
            encoding: r.string("encoding")?,
            is_bigendian: r.u8("is_bigendian")?,
            step: r.u32("step")?,
            data: r.bytes("data")?,
        })
    }
}

/// The size an [`Image`] payload declares, read without copying its pixels, so a receiver
/// can check it against its limits before it allocates anything for the image.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImageLayout {
    /// `width` of the message.
    pub width: u32,
    /// `height` of the message.
    pub height: u32,
    /// `step` of the message (bytes per row).
    pub step: u32,
    /// The length of `data` as declared (not checked against the bytes present).
    pub data_len: u32,
}

impl ImageLayout {
    /// The layout of an `Image` payload (encapsulation header first): the fields are read
    /// up to and including the data's length; the data itself is neither read nor copied.
    pub fn peek(payload: &[u8]) -> Result<Self, DecodeError> {
        let mut r = CdrReader::new(payload)?;
        Header::read(&mut r)?;
        let height = r.u32("height")?;
        let width = r.u32("width")?;
        r.string("encoding")?;
        r.u8("is_bigendian")?;
        let step = r.u32("step")?;
        let data_len = r.u32("data")?;
        Ok(Self {
            width,
            height,
            step,
            data_len,
        })
    }
}

/// `sensor_msgs/msg/CompressedImage`: an encoded image file, as `image_transport`'s
/// `compressed` transport publishes it on `<image topic>/compressed`.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CompressedImage {
    /// Capture time and the camera's optical frame.
    pub header: Header,
    /// What `data` holds: `jpeg` or `png`, or as compressed_image_transport writes it,
    /// `ORIG_PIXFMT; CODEC compressed [COMPRESSED_PIXFMT]` (`rgb8; jpeg compressed bgr8`).
    pub format: String,
    /// The encoded file's bytes.
    pub data: Vec<u8>,
}

impl Message for CompressedImage {
    const KIND: MessageKind = MessageKind::CompressedImage;

    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.string(&self.format);
        w.bytes(&self.data);
    }

    /// The data and room for the header and format.
    fn size_hint(&self) -> usize {
        self.data.len() + self.format.len() + self.header.frame_id.len() + 32
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(r)?,
            format: r.string("format")?,
            data: r.bytes("data")?,
        })
    }
}

/// `sensor_msgs/msg/RegionOfInterest`: a sub-window of an image (all zero: the full image).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct RegionOfInterest {
    /// Leftmost column.
    pub x_offset: u32,
    /// Topmost row.
    pub y_offset: u32,
    /// Rows.
    pub height: u32,
    /// Columns.
    pub width: u32,
    /// Whether the window should be rectified.
    pub do_rectify: bool,
}

impl Message for RegionOfInterest {
    const KIND: MessageKind = MessageKind::RegionOfInterest;

    fn write(&self, w: &mut CdrWriter) {
        w.u32(self.x_offset);
        w.u32(self.y_offset);
        w.u32(self.height);
        w.u32(self.width);
        w.bool(self.do_rectify);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            x_offset: r.u32("roi.x_offset")?,
            y_offset: r.u32("roi.y_offset")?,
            height: r.u32("roi.height")?,
            width: r.u32("roi.width")?,
            do_rectify: r.bool("roi.do_rectify")?,
        })
    }
}

/// `sensor_msgs/msg/CameraInfo`: calibration of one camera (row-major matrices).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct CameraInfo {
    /// Capture time and the camera's optical frame.
    pub header: Header,
    /// Image rows the calibration applies to.
    pub height: u32,
    /// Image columns.
    pub width: u32,
    /// Distortion model name (`plumb_bob`, ...).
    pub distortion_model: String,
    /// Distortion coefficients.
    pub d: Vec<f64>,
    /// 3x3 intrinsic matrix of the raw images.
    pub k: [f64; 9],
    /// 3x3 rectification rotation.
    pub r: [f64; 9],
    /// 3x4 projection matrix of the rectified images; `p[3] = -fx * baseline` for the right
    /// camera of a stereo pair.
    pub p: [f64; 12],
    /// Horizontal binning (0 or 1: none).
    pub binning_x: u32,
    /// Vertical binning.
    pub binning_y: u32,
    /// Region of interest (all zero: the full image).
    pub roi: RegionOfInterest,
}

impl Message for CameraInfo {
    const KIND: MessageKind = MessageKind::CameraInfo;

    fn write(&self, w: &mut CdrWriter) {
        self.header.write(w);
        w.u32(self.height);
        w.u32(self.width);
        w.string(&self.distortion_model);
        w.f64_seq(&self.d);
        w.f64_array(&self.k);
        w.f64_array(&self.r);
        w.f64_array(&self.p);
        w.u32(self.binning_x);
        w.u32(self.binning_y);
        self.roi.write(w);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            header: Header::read(r)?,
            height: r.u32("height")?,
            width: r.u32("width")?,
            distortion_model: r.string("distortion_model")?,
            d: r.f64_seq("d")?,
            k: r.f64_array("k")?,
            r: r.f64_array("r")?,
            p: r.f64_array("p")?,
            binning_x: r.u32("binning_x")?,
            binning_y: r.u32("binning_y")?,
            roi: RegionOfInterest::read(r)?,
        })
    }
}

/// The `datatype` codes of `sensor_msgs/msg/PointField`.
pub mod datatype {
    /// `int8`.
    pub const INT8: u8 = 1;
    /// `uint8`.
    pub const UINT8: u8 = 2;
    /// `int16`.
    pub const INT16: u8 = 3;
    /// `uint16`.
    pub const UINT16: u8 = 4;
    /// `int32`.
    pub const INT32: u8 = 5;
    /// `uint32`.
    pub const UINT32: u8 = 6;
    /// `float32`.
    pub const FLOAT32: u8 = 7;
    /// `float64`.
    pub const FLOAT64: u8 = 8;
}

/// `sensor_msgs/msg/PointField`: one named channel of a point record.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PointField {
    /// Channel name (`x`, `opacity`, ...).
    pub name: String,
    /// Byte offset within the point record.
    pub offset: u32,
    /// Element type, one of [`datatype`].
    pub datatype: u8,
    /// Elements in the channel (1 for scalars).
    pub count: u32,
}

/// Fewest bytes one `PointField` can take on the wire (no padding): string length and NUL,
/// offset, datatype, count.
const POINT_FIELD_MIN_BYTES: usize = 4 + 1 + 4 + 1 + 4;

impl Message for PointField {
    const KIND: MessageKind = MessageKind::PointField;

    fn write(&self, w: &mut CdrWriter) {
        w.string(&self.name);
        w.u32(self.offset);
        w.u8(self.datatype);
        w.u32(self.count);
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        Ok(Self {
            name: r.string("fields.name")?,
            offset: r.u32("fields.offset")?,
            datatype: r.u8("fields.datatype")?,
            count: r.u32("fields.count")?,
        })
    }
}

/// `sensor_msgs/msg/PointCloud2`: `height` rows of `width` point records of `point_step`
/// bytes, laid out as `fields` say.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct PointCloud2 {
    /// Time and the frame the points are expressed in.
    pub header: Header,
    /// Rows (1 for an unordered cloud).
    pub height: u32,
    /// Points per row.
    pub width: u32,
    /// The channels of a point record.
    pub fields: Vec<PointField>,
    /// Whether multi-byte values are big endian.
    pub is_bigendian: bool,
    /// Bytes per point.
    pub point_step: u32,
    /// Bytes per row.
    pub row_step: u32,
    /// `row_step * height` bytes.
    pub data: Vec<u8>,
    /// True when no point holds a non-finite value.
    pub is_dense: bool,
}

impl PointCloud2 {
    /// Writes the cloud with `n` bytes of data that `data` appends in place of
    /// [`PointCloud2::data`] (which is not written): a large cloud goes straight into the
    /// payload instead of being built beside it.
    pub fn write_with_data(&self, w: &mut CdrWriter, n: usize, data: impl FnOnce(&mut Vec<u8>)) {
        self.header.write(w);
        w.u32(self.height);
        w.u32(self.width);
        w.seq_len(self.fields.len());
        for f in &self.fields {
            f.write(w);
        }
        w.bool(self.is_bigendian);
        w.u32(self.point_step);
        w.u32(self.row_step);
        w.bytes_from(n, data);
        w.bool(self.is_dense);
    }
}

impl Message for PointCloud2 {
    const KIND: MessageKind = MessageKind::PointCloud2;

    fn write(&self, w: &mut CdrWriter) {
        self.write_with_data(w, self.data.len(), |b| b.extend_from_slice(&self.data));
    }

    /// The data and room for the header and field descriptions.
    fn size_hint(&self) -> usize {
        self.data.len() + 64 * self.fields.len() + 256
    }

    fn read(r: &mut CdrReader<'_>) -> Result<Self, DecodeError> {
        let header = Header::read(r)?;
        let height = r.u32("height")?;
        let width = r.u32("width")?;
        let n = r.seq_len("fields", POINT_FIELD_MIN_BYTES)?;
        let fields = (0..n)
            .map(|_| PointField::read(r))
            .collect::<Result<_, _>>()?;
        Ok(Self {
            header,
            height,
            width,
            fields,
            is_bigendian: r.bool("is_bigendian")?,
            point_step: r.u32("point_step")?,
            row_step: r.u32("row_step")?,
            data: r.bytes("data")?,
            is_dense: r.bool("is_dense")?,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::msg::Message;

    #[test]
    fn the_layout_is_the_image_without_its_pixels() {
        let image = Image {
            header: Header::new(7, "left"),
            height: 2,
            width: 3,
            encoding: "rgb8".into(),
            is_bigendian: 0,
            step: 9,
            data: (0..18).collect(),
        };
        let bytes = image.encode();
        let layout = ImageLayout::peek(&bytes).unwrap();
        assert_eq!(
            (layout.width, layout.height, layout.step, layout.data_len),
            (3, 2, 9, 18)
        );
        // The data is not needed, so a payload cut inside it still has its layout; one cut
        // before the data's length does not.
        assert_eq!(
            ImageLayout::peek(&bytes[..bytes.len() - 5])
                .unwrap()
                .data_len,
            18
        );
        let at_len = bytes.len() - 18;
        assert!(ImageLayout::peek(&bytes[..at_len]).is_ok());
        for cut in 0..at_len {
            assert!(ImageLayout::peek(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }
}
