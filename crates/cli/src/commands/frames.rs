//! `pingcal frames BAG... --cloud-topic T --image-topic T --camera camera.toml
//! --sphere-diameter-mm D --out DIR`: the frames of a single-sphere calibration, taken from
//! a bag's `sensor_msgs/PointCloud2` and `sensor_msgs/Image` / `CompressedImage` topics.
//!
//! A first pass measures how much each cloud and each image moved from the one before
//! ([`pingcal_rosbag::frames`]) and finds the moments when the sphere stands still in both;
//! each such moment gives one frame, the cloud nearest its middle paired with the image
//! nearest that cloud's stamp. A second pass writes them: `DIR/clouds/F01.xyz` (`x y z`
//! in metres, then `intensity` and `ring` where the cloud has them), `DIR/images/F01.png`
//! (a raw image as PNG; a compressed one as the JPEG or PNG it is), the camera file as
//! `DIR/camera.toml`, and `DIR/sphere-calib.toml`, which `pingcal sphere-calib` runs as it
//! is. Every file is written atomically.

use super::CmdResult;
use pingcal_project::{CameraFile, SphereCalibFile, SphereCalibFrame, SphereCalibLidar};
use pingcal_rosbag::frames::{
    cloud_motion, cloud_signature, compressed_thumb, image_motion, image_thumb, pair_moments,
    still_runs, CloudGrid, FramePair, Thumb, MIN_STILL_CLOUD, MIN_STILL_IMAGE,
};
use pingcal_rosbag::msgs::{self, CompressedImage, Image, PointCloud2};
use pingcal_rosbag::{Bag, RawMessage, RosbagError};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Arguments of `pingcal frames`.
#[derive(clap::Args)]
pub struct Args {
    /// Bags: ROS 1 `.bag`, ROS 2 `.mcap` or `.db3`, or a ROS 2 bag folder.
    #[arg(required = true)]
    pub bags: Vec<PathBuf>,
    /// The `sensor_msgs/PointCloud2` topic (the lidar).
    #[arg(long)]
    pub cloud_topic: String,
    /// The `sensor_msgs/Image` or `sensor_msgs/CompressedImage` topic (the camera).
    #[arg(long)]
    pub image_topic: String,
    /// The camera's intrinsics, in any form `pingcal sphere-calib` reads (written as `camera.toml`).
    #[arg(long)]
    pub camera: PathBuf,
    /// The sphere's diameter, mm.
    #[arg(long)]
    pub sphere_diameter_mm: f64,
    /// The lidar's range-noise profile (`VLP-16`, `UTM-30LX`, `UST-10LX`, `URG-04LX`).
    #[arg(long, default_value = "VLP-16")]
    pub noise: pingcal_lrf::sensor::NoiseProfile,
    /// The folder to write (created if absent).
    #[arg(long)]
    pub out: PathBuf,
}

/// The first pass's measures of one topic: each message's stamp and motion from the one
/// before.
#[derive(Default)]
struct Track {
    stamps: Vec<i64>,
    motions: Vec<f64>,
}

impl Track {
    fn push(&mut self, stamp: i64, motion: f64) {
        self.stamps.push(stamp);
        self.motions.push(motion);
    }
}

fn decode_err(bag: &Bag, m: &RawMessage, e: String) -> RosbagError {
    RosbagError::topic(bag.name(), m.topic, format!("a {}: {e}", m.msg_type))
}

fn expect(bag: &Bag, m: &RawMessage, types: &[&str]) -> Result<(), RosbagError> {
    if types.contains(&m.msg_type) {
        return Ok(());
    }
    Err(RosbagError::WrongType {
        file: bag.name().to_string(),
        topic: m.topic.to_string(),
        found: m.msg_type.to_string(),
        expected: types.join(" or "),
    })
}

/// The thumbnail of an image message of either type, and its stamp.
fn thumb(m: &RawMessage) -> Result<(i64, Thumb), String> {
    if m.msg_type == msgs::IMAGE {
        let img = Image::decode(m.data, m.encoding)?;
        Ok((img.stamp_ns, image_thumb(&img)?))
    } else {
        let img = CompressedImage::decode(m.data, m.encoding)?;
        Ok((img.stamp_ns, compressed_thumb(&img)?))
    }
}

/// First pass: the stamps and motions of the clouds and the images.
fn measure(bags: &[Bag], args: &Args) -> Result<(Track, Track), RosbagError> {
    let (mut clouds, mut images) = (Track::default(), Track::default());
    let mut last_cloud: Option<CloudGrid> = None;
    let mut last_thumb: Option<Thumb> = None;
    let topics = [args.cloud_topic.as_str(), args.image_topic.as_str()];
    for bag in bags {
        bag.for_each(&topics, &mut |m| {
            if m.topic == args.cloud_topic {
                expect(bag, m, &[msgs::POINT_CLOUD2])?;
                let c =
                    PointCloud2::decode(m.data, m.encoding).map_err(|e| decode_err(bag, m, e))?;
                let sig = cloud_signature(&c);
                let motion = last_cloud
                    .as_ref()
                    .map_or(f64::INFINITY, |l| cloud_motion(l, &sig));
                clouds.push(c.stamp_ns, motion);
                last_cloud = Some(sig);
            } else {
                expect(bag, m, &[msgs::IMAGE, msgs::COMPRESSED_IMAGE])?;
                let (stamp, t) = thumb(m).map_err(|e| decode_err(bag, m, e))?;
                let motion = last_thumb
                    .as_ref()
                    .map_or(f64::INFINITY, |l| image_motion(l, &t));
                images.push(stamp, motion);
                last_thumb = Some(t);
            }
            Ok(())
        })?;
    }
    Ok((clouds, images))
}

/// Second pass: the chosen clouds and images, written as frame files; the frames' entries.
fn write_frames(
    bags: &[Bag],
    args: &Args,
    pairs: &[FramePair],
) -> Result<Vec<SphereCalibFrame>, super::CmdError> {
    let id = |k: usize| format!("F{:02}", k + 1);
    let cloud_of: BTreeMap<i64, usize> = pairs
        .iter()
        .enumerate()
        .map(|(k, p)| (p.cloud_ns, k))
        .collect();
    let image_of: BTreeMap<i64, usize> = pairs
        .iter()
        .enumerate()
        .map(|(k, p)| (p.image_ns, k))
        .collect();
    let mut clouds: Vec<Option<String>> = vec![None; pairs.len()];
    let mut images: Vec<Option<String>> = vec![None; pairs.len()];
    for d in ["clouds", "images"] {
        std::fs::create_dir_all(args.out.join(d))
            .map_err(|e| format!("{}: cannot create: {e}", args.out.join(d).display()))?;
    }
    let mut failed: Option<super::CmdError> = None;
    let topics = [args.cloud_topic.as_str(), args.image_topic.as_str()];
    for bag in bags {
        bag.for_each(&topics, &mut |m| {
            let write = |rel: String, bytes: &[u8]| -> Result<String, super::CmdError> {
                super::write_atomic(&args.out.join(&rel), bytes)?;
                Ok(rel)
            };
            let r = if m.topic == args.cloud_topic {
                let c =
                    PointCloud2::decode(m.data, m.encoding).map_err(|e| decode_err(bag, m, e))?;
                match cloud_of.get(&c.stamp_ns) {
                    Some(&k) if clouds[k].is_none() => write(
                        format!("clouds/{}.xyz", id(k)),
                        pingcal_rosbag::frames::cloud_text(&c, m.topic).as_bytes(),
                    )
                    .map(|f| clouds[k] = Some(f)),
                    _ => Ok(()),
                }
            } else {
                let (stamp, _) = thumb(m).map_err(|e| decode_err(bag, m, e))?;
                match image_of.get(&stamp) {
                    Some(&k) if images[k].is_none() => {
                        let (ext, bytes) = pingcal_rosbag::frames::image_file(m)
                            .map_err(|e| decode_err(bag, m, e))?;
                        write(format!("images/{}.{ext}", id(k)), &bytes)
                            .map(|f| images[k] = Some(f))
                    }
                    _ => Ok(()),
                }
            };
            r.map_err(|e| {
                let msg = e.to_string();
                failed = Some(e);
                RosbagError::Io {
                    file: bag.name().to_string(),
                    msg,
                }
            })
        })
        .map_err(|e| failed.take().unwrap_or_else(|| e.into()))?;
    }
    Ok(clouds
        .into_iter()
        .zip(images)
        .enumerate()
        .filter_map(|(k, (c, i))| {
            Some(SphereCalibFrame {
                id: Some(id(k)),
                cloud: c?,
                image: i?,
            })
        })
        .collect())
}

/// Runs the command.
pub fn run(args: Args) -> CmdResult {
    if !(args.sphere_diameter_mm.is_finite() && args.sphere_diameter_mm > 0.0) {
        return Err(format!(
            "--sphere-diameter-mm {}: expected a positive diameter",
            args.sphere_diameter_mm
        )
        .into());
    }
    let cam_name = args.camera.display().to_string();
    let cam_text = std::fs::read_to_string(&args.camera)
        .map_err(|e| format!("{cam_name}: cannot read: {e}"))?;
    // any form sphere-calib reads; written as camera.toml
    let camera = CameraFile::read(&cam_text, &cam_name, None)?;
    let cam_text = match camera.format {
        pingcal_project::CameraFormat::Toml => cam_text,
        _ => camera.to_toml_string(),
    };
    let bags = super::scans::open_bags(&args.bags)?;
    let (clouds, images) = measure(&bags, &args)?;
    if clouds.stamps.is_empty() || images.stamps.is_empty() {
        return Err(format!(
            "{} clouds on {} and {} images on {}: both are needed",
            clouds.stamps.len(),
            args.cloud_topic,
            images.stamps.len(),
            args.image_topic
        )
        .into());
    }
    let cloud_runs = still_runs(&clouds.stamps, &clouds.motions, MIN_STILL_CLOUD);
    let image_runs = still_runs(&images.stamps, &images.motions, MIN_STILL_IMAGE);
    let sorted = |v: &[i64]| {
        let mut s = v.to_vec();
        s.sort_unstable();
        s
    };
    let pairs = pair_moments(
        &cloud_runs,
        &sorted(&clouds.stamps),
        &image_runs,
        &sorted(&images.stamps),
    );
    if pairs.is_empty() {
        return Err(format!(
            "no moment when the scene stands still in both: {} still moment(s) among {} clouds, {} among {} images",
            cloud_runs.len(),
            clouds.stamps.len(),
            image_runs.len(),
            images.stamps.len()
        )
        .into());
    }
    let frames = write_frames(&bags, &args, &pairs)?;
    super::write_atomic(&args.out.join("camera.toml"), cam_text.as_bytes())?;
    let project = SphereCalibFile {
        version: 1,
        name: Some(format!("frames of {}", bag_names(&args.bags))),
        camera: "camera.toml".into(),
        camera_entry: None,
        sphere_diameter_mm: args.sphere_diameter_mm,
        lidar: SphereCalibLidar {
            unit: pingcal_lrf::cloud_file::CloudUnit::M,
            noise: Some(args.noise),
            noise_sigma_mm: None,
            model: None,
        },
        frames,
    };
    let toml = args.out.join("sphere-calib.toml");
    super::write_atomic(&toml, project.to_toml_string().as_bytes())?;
    println!(
        "frames: {} frames from {} clouds and {} images ({} still moment(s) of the clouds, {} of the images) → {}",
        project.frames.len(),
        clouds.stamps.len(),
        images.stamps.len(),
        cloud_runs.len(),
        image_runs.len(),
        toml.display()
    );
    if project.frames.len() < 3 {
        eprintln!(
            "pingcal: warning: {} frame(s): sphere-calib needs 3 at least (6 or more advised)",
            project.frames.len()
        );
    }
    Ok(())
}

fn bag_names(paths: &[PathBuf]) -> String {
    paths
        .iter()
        .map(|p| {
            p.file_name().map_or_else(
                || p.display().to_string(),
                |n| n.to_string_lossy().into_owned(),
            )
        })
        .collect::<Vec<_>>()
        .join(", ")
}
