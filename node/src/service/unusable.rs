//! Why an input sample (or an image of a frame that opens a bin) was not used: the one
//! error of the input side ([`super::inputs`], [`super::input_image`]). Each is counted
//! against its topic (`bad_message/<topic>`), a refusal under its reason as well.

use super::limits::Refusal;
use crate::msg::cdr::DecodeError;
use crate::msg::compressed::CompressedError;
use crate::msg::ConvertError;
use crate::rectify::RemapError;

/// Why an input was not used.
#[derive(Debug, thiserror::Error)]
pub(super) enum Unusable {
    /// Not a CDR payload of the key's type.
    #[error(transparent)]
    Decode(#[from] DecodeError),
    /// Well-formed, but its content cannot become the node's types (an encoding the node
    /// does not read, data that disagrees with the size, a pose that is not rigid).
    #[error(transparent)]
    Convert(#[from] ConvertError),
    /// A compressed image that is not a JPEG or PNG the node can read.
    #[error(transparent)]
    Compressed(#[from] CompressedError),
    /// Outside the input limits.
    #[error(transparent)]
    Refused(#[from] Refusal),
    /// An image not of the size its camera's rectification was built for.
    #[error("rectifying: {0}")]
    Rectify(#[from] RemapError),
}
