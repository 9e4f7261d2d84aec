//! The synthetic street generator: deterministic forward-driving stereo sequences of a
//! procedural street (road with lane marks, kerbs, sidewalks, facades with windows, plain
//! walls, parked and oncoming cars, poles, trees, sky) with exact left depth and
//! HDL-64E-like LiDAR sweeps, rendered by ray casting analytic primitives.
//!
//! World frame: x, y on the ground, z up (as KITTI-360's world). Camera poses are OpenCV
//! camera-to-world (x right, y down, z forward). The same seed gives bit-identical output:
//! every random choice comes from ChaCha streams keyed by (seed, purpose, segment), and
//! every pixel and LiDAR ray is computed independently of thread scheduling.

mod camera_effects;
mod camera_render;
mod config;
mod lidar;
mod photos;
mod primitives;
mod randomise;
mod scene;
mod shading;
mod textures;
mod trace;
mod trajectory;

use glam::DAffine3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use camera_render::camera_ray;
pub use config::SynthConfig;
pub use lidar::{BOTTOM_ELEVATION, RINGS, TOP_ELEVATION};
pub use photos::PhotoBank;
pub use primitives::Ray;
pub use randomise::{CameraLook, DriveLook, Randomisation};
pub use shading::SurfaceClass;
pub use trace::KERB_HEIGHT;
pub use trajectory::{CAMERA_HEIGHT, FRAME_DT};

use crate::frame::{DepthMap, Side, StereoFrame, StereoRig};
use scene::{Street, ONCOMING_SPEED};
use shading::Palette;
use textures::mix64;
use trace::World;
use trajectory::{Road, Trajectory};

/// How far along the road (both ways) a frame considers objects, metres.
const OBJECT_RANGE: f64 = 150.0;

/// One generated frame: the stereo pair with its pose, both cameras' exact z-depth (0 = sky)
/// and a LiDAR sweep in the velodyne frame (`[x, y, z, reflectance]`).
#[derive(Clone, Debug, PartialEq)]
pub struct SynthFrame {
    /// Left and right images and the left camera's pose.
    pub frame: StereoFrame,
    /// Left camera z-depth per pixel centre, metres; 0 where the sky is seen.
    pub left_depth: DepthMap,
    /// Right camera z-depth per pixel centre, metres; 0 where the sky is seen.
    pub right_depth: DepthMap,
    /// LiDAR points in the velodyne frame, as a KITTI `.bin` holds them.
    pub lidar: Vec<[f32; 4]>,
}

/// A synthetic sequence: frames are rendered on demand, each from only the scene near it.
#[derive(Clone, Debug)]
pub struct SynthSequence {
    config: SynthConfig,
    rig: StereoRig,
    cam_to_velo: DAffine3,
    road: Road,
    street: Street,
    trajectory: Trajectory,
    palette: Palette,
    look: Option<DriveLook>,
}

fn stream(seed: u64, purpose: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix64(seed ^ mix64(purpose)))
}

impl SynthSequence {
    /// A sequence for `config`, seen by `rig`, with the velodyne at `cam_to_velo` (maps left
    /// camera coordinates to velodyne coordinates).
    pub fn new(config: SynthConfig, rig: StereoRig, cam_to_velo: DAffine3) -> Self {
        let trajectory = Trajectory::new(&mut stream(config.seed, 1), config.frames);
        let duration = config.frames as f64 * FRAME_DT;
        let length = trajectory.end_arc() + ONCOMING_SPEED * duration + 2.0 * OBJECT_RANGE;
        let mut palette = Palette::new(&mut stream(config.seed, 3));
        if let Some(r) = &config.randomise {
            palette.randomise(&mut stream(config.seed, 5), r);
        }
        Self {
            config,
            rig,
            cam_to_velo,
            road: Road::new(&mut stream(config.seed, 2), length),
            street: Street::new(config.seed, config.randomise),
            trajectory,
            palette,
            look: config.look(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SynthConfig {
        &self.config
    }

    /// The stereo rig.
    pub fn rig(&self) -> &StereoRig {
        &self.rig
    }

    /// Number of frames (`config.frames`).
    pub fn len(&self) -> usize {
        self.config.frames as usize
    }

    /// Whether the sequence has no frames.
    pub fn is_empty(&self) -> bool {
        self.config.frames == 0
    }

    /// Left camera to world at frame `i` (cheap: no rendering). Indices past `len()` continue
    /// the same drive.
    pub fn pose(&self, i: usize) -> DAffine3 {
        self.trajectory.pose(&self.road, i)
    }

    /// Timestamp of frame `i` in nanoseconds (10 Hz from 0).
    pub fn timestamp_ns(&self, i: usize) -> i64 {
        i as i64 * 100_000_000
    }

    fn world(&self, i: usize) -> World<'_> {
        let arc = self.trajectory.arc(i);
        let time = i as f64 * FRAME_DT;
        let objects = self
            .street
            .objects_near(&self.road, &self.palette, arc, OBJECT_RANGE, time);
        World::new(
            &self.road,
            &self.palette,
            objects,
            arc,
            self.pose(i).translation,
        )
    }

    /// Renders frame `i`: both images, both depths and the LiDAR sweep.
    pub fn frame(&self, i: usize) -> SynthFrame {
        let world = self.world(i);
        let left_pose = self.pose(i);
        let right_pose = self.rig.camera_to_world(left_pose, Side::Right);
        let k = &self.rig.intrinsics;
        let ss = self.config.supersample;
        let mut left = camera_render::render_image(&world, &left_pose, k, ss);
        let mut right = camera_render::render_image(&world, &right_pose, k, ss);
        if let Some(look) = &self.look {
            // Per-frame noise: its own stream per (seed, frame).
            let mut rng = stream(self.config.seed ^ mix64(i as u64), 6);
            camera_effects::apply(&mut left, &look.camera, look.camera.gain_left, &mut rng);
            camera_effects::apply(&mut right, &look.camera, look.camera.gain_right, &mut rng);
        }
        let (left_depth, _) = camera_render::render_centres(&world, &left_pose, k);
        let (right_depth, _) = camera_render::render_centres(&world, &right_pose, k);
        let velo_to_world = left_pose * self.cam_to_velo.inverse();
        let lidar = lidar::scan(
            &world,
            &velo_to_world,
            self.config.lidar_azimuth_steps,
            self.config.lidar_max_range,
        );
        SynthFrame {
            frame: StereoFrame {
                index: i as u32,
                left,
                right,
                left_to_world: left_pose,
            },
            left_depth,
            right_depth,
            lidar,
        }
    }

    /// The class of the surface through each left-camera pixel centre at frame `i`, row
    /// major (for checking what a sequence shows).
    pub fn left_classes(&self, i: usize) -> Vec<SurfaceClass> {
        let world = self.world(i);
        camera_render::render_centres(&world, &self.pose(i), &self.rig.intrinsics).1
    }
}
