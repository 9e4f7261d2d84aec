//! The synthetic scene generator: deterministic stereo sequences with exact depth of both
//! cameras and HDL-64E-like LiDAR sweeps, rendered by ray casting analytic primitives, of
//! three kinds ([`SceneKind`]): a car driving down a procedural street (road with lane
//! marks, kerbs, sidewalks, facades with windows, plain walls, parked and oncoming cars,
//! poles, trees, sky; 1-100 m), a handheld camera over a desk (objects and hands on a
//! table 0.2-1 m away) and one walking through a furnished room (1-10 m).
//!
//! World frame: x, y on the ground, z up (as KITTI-360's world). Camera poses are OpenCV
//! camera-to-world (x right, y down, z forward). The same seed gives bit-identical output:
//! every random choice comes from ChaCha streams keyed by (seed, purpose, segment), and
//! every pixel and LiDAR ray is computed independently of thread scheduling.

mod camera_effects;
mod camera_render;
mod config;
mod desk;
mod indoor;
mod lidar;
mod photos;
mod primitives;
mod randomise;
mod room;
mod scene;
mod scene_kind;
mod shading;
mod textures;
mod trace;
mod trajectory;

use glam::DAffine3;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;

pub use camera_render::camera_ray;
pub use config::{SynthConfig, SynthConfigError};
pub use desk::{TABLE_HEIGHT, VIEW_DISTANCE_M as DESK_VIEW_DISTANCE_M};
pub use lidar::{BOTTOM_ELEVATION, RINGS, TOP_ELEVATION};
pub use photos::PhotoBank;
pub use primitives::Ray;
pub use randomise::{CameraLook, DriveLook, Randomisation, HANDHELD_SIZES};
pub use room::VIEW_DISTANCE_M as ROOM_VIEW_DISTANCE_M;
pub use scene_kind::{RigChoice, SceneKind};
pub use shading::SurfaceClass;
pub use trace::KERB_HEIGHT;
pub use trajectory::{CAMERA_HEIGHT, FRAME_DT};

use crate::frame::{DepthMap, RgbImage, Side, StereoFrame, StereoRig};
use indoor::IndoorScene;
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
    layout: Layout,
    palette: Palette,
    look: Option<DriveLook>,
}

/// Where the camera is and what surrounds it. One per sequence, never stored in bulk, so
/// the street variant's size costs nothing worth a box.
#[derive(Clone, Debug)]
#[allow(clippy::large_enum_variant)]
enum Layout {
    /// A road, its furniture and the car's motion along it.
    Street {
        road: Road,
        street: Street,
        trajectory: Trajectory,
    },
    /// A desk or a room with its handheld path.
    Indoor(IndoorScene),
}

fn stream(seed: u64, purpose: u64) -> ChaCha8Rng {
    ChaCha8Rng::seed_from_u64(mix64(seed ^ mix64(purpose)))
}

impl SynthSequence {
    /// A sequence for `config`, seen by `rig`, with the velodyne at `cam_to_velo` (maps left
    /// camera coordinates to velodyne coordinates).
    pub fn new(config: SynthConfig, rig: StereoRig, cam_to_velo: DAffine3) -> Self {
        let (layout, palette) = match config.scene {
            SceneKind::Street => Self::street(&config),
            kind => {
                // Streams 1-6 belong to the street and the camera look.
                let palette =
                    indoor::lighting(&mut stream(config.seed, 8), config.randomise.as_ref());
                let rng = &mut stream(config.seed, 7);
                let scene = match kind {
                    SceneKind::Desk => desk::build(rng, &config, &rig.intrinsics),
                    _ => room::build(rng, &config),
                };
                (Layout::Indoor(scene), palette)
            }
        };
        Self {
            config,
            rig,
            cam_to_velo,
            layout,
            palette,
            look: config.look(),
        }
    }

    /// The street of `config`, and its light.
    fn street(config: &SynthConfig) -> (Layout, Palette) {
        let trajectory = Trajectory::new(&mut stream(config.seed, 1), config.frames);
        let duration = config.frames as f64 * FRAME_DT;
        let length = trajectory.end_arc() + ONCOMING_SPEED * duration + 2.0 * OBJECT_RANGE;
        let mut palette = Palette::new(&mut stream(config.seed, 3));
        if let Some(r) = &config.randomise {
            palette.randomise(&mut stream(config.seed, 5), r);
        }
        let layout = Layout::Street {
            road: Road::new(&mut stream(config.seed, 2), length),
            street: Street::new(config.seed, config.randomise),
            trajectory,
        };
        (layout, palette)
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
        match &self.layout {
            Layout::Street {
                road, trajectory, ..
            } => trajectory.pose(road, i),
            Layout::Indoor(scene) => scene.path.pose(i),
        }
    }

    /// Timestamp of frame `i` in nanoseconds (10 Hz from 0).
    pub fn timestamp_ns(&self, i: usize) -> i64 {
        i as i64 * 100_000_000
    }

    fn world(&self, i: usize) -> World<'_> {
        let anchor = self.pose(i).translation;
        match &self.layout {
            Layout::Street {
                road,
                street,
                trajectory,
            } => {
                let arc = trajectory.arc(i);
                let time = i as f64 * FRAME_DT;
                let objects = street.objects_near(road, &self.palette, arc, OBJECT_RANGE, time);
                World::new(road, &self.palette, objects, arc, anchor)
            }
            Layout::Indoor(scene) => World::indoor(
                &self.palette,
                scene.objects.clone(),
                anchor,
                scene.path.tangent(),
            ),
        }
    }

    /// The image of one camera: rendered, exposed, then spoiled by the drive's look.
    fn image(
        &self,
        world: &World,
        pose: &DAffine3,
        gain: impl Fn(&DriveLook) -> glam::DVec3,
        rng: &mut ChaCha8Rng,
    ) -> RgbImage {
        let k = &self.rig.intrinsics;
        let mut image = camera_render::render_image(world, pose, k, self.config.supersample);
        if self.config.exposure != 1.0 {
            let exposure = self.config.exposure as f32;
            for v in &mut image.data {
                *v = (*v * exposure).clamp(0.0, 1.0);
            }
        }
        if let Some(look) = &self.look {
            camera_effects::apply(&mut image, &look.camera, gain(look), rng);
        }
        image
    }

    /// Renders frame `i`: both images, both depths and the LiDAR sweep.
    pub fn frame(&self, i: usize) -> SynthFrame {
        let world = self.world(i);
        let left_pose = self.pose(i);
        let right_pose = self.rig.camera_to_world(left_pose, Side::Right);
        let k = &self.rig.intrinsics;
        // Per-frame noise: its own stream per (seed, frame).
        let mut rng = stream(self.config.seed ^ mix64(i as u64), 6);
        let left = self.image(&world, &left_pose, |l| l.camera.gain_left, &mut rng);
        let right = self.image(&world, &right_pose, |l| l.camera.gain_right, &mut rng);
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
