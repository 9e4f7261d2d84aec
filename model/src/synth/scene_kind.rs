//! The kinds of scene the generator draws ([`SceneKind`]) and the hand-chosen rig of each
//! ([`RigChoice`]); the settings of a sequence ([`super::SynthConfig`]) and its
//! randomisation ([`super::randomise`]) both name them.

/// What a sequence shows, and so the scale of its depths.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum SceneKind {
    /// A car rig driving down a procedural street: surfaces at 1-100 m.
    #[default]
    Street,
    /// A handheld or arm-mounted rig over a table with objects and hands on it: the table
    /// top 0.2-1 m away, a backdrop behind at 1-3 m.
    Desk,
    /// A handheld rig walking through a furnished room: floor, walls and ceiling 1-10 m away.
    Room,
}

impl SceneKind {
    /// Every kind, in the order the docs list them.
    pub const ALL: [SceneKind; 3] = [SceneKind::Street, SceneKind::Desk, SceneKind::Room];

    /// The lower-case name the command line and sequence names use.
    pub fn name(self) -> &'static str {
        match self {
            SceneKind::Street => "street",
            SceneKind::Desk => "desk",
            SceneKind::Room => "room",
        }
    }

    /// The kind called `name` ([`SceneKind::name`]), if any.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The rig of an unrandomised sequence of this kind: `None` for a street (KITTI-360's
    /// own), a 10 cm, 70 degree rig for a desk (a stereo webcam or OAK-D class camera) and
    /// a 12 cm, 75 degree one for a room.
    pub fn rig(self) -> Option<RigChoice> {
        match self {
            SceneKind::Street => None,
            SceneKind::Desk => Some(RigChoice {
                hfov_deg: 70.0,
                baseline_m: 0.10,
            }),
            SceneKind::Room => Some(RigChoice {
                hfov_deg: 75.0,
                baseline_m: 0.12,
            }),
        }
    }
}

/// A stereo rig chosen by hand: square pixels, principal point at the image centre.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RigChoice {
    /// Horizontal field of view, degrees (the focal length follows from the image width).
    pub hfov_deg: f64,
    /// Distance between the two cameras, metres.
    pub baseline_m: f64,
}

impl RigChoice {
    /// The focal length in pixels of this field of view at `width` pixels.
    pub fn focal_px(&self, width: u32) -> f64 {
        0.5 * width as f64 / (0.5 * self.hfov_deg.to_radians()).tan()
    }
}
