//! The streaming benchmark's reader (bench/rosbag/run.sh): reads a bag's servo series and
//! every LaserScan in one pass, decoded and assembled exactly as `pingcal scans` does (servo
//! motion `auto`), without writing anything, and prints the bag's bytes over the wall time and the peak resident memory.
//!
//! `cargo run --release -p pingcal-rosbag --example read_bag -- BAG SCAN_TOPIC SERVO_TOPIC JOINT`

use pingcal_rosbag::assemble::{read_scans, ServoMotion, ServoSource, Topics};
use pingcal_rosbag::{bag_files, Bag};

fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let [path, scan, servo, joint] = a.as_slice() else {
        return Err("usage: read_bag BAG SCAN_TOPIC SERVO_TOPIC JOINT".into());
    };
    let t0 = std::time::Instant::now();
    let mut bags = Vec::new();
    let mut bytes = 0u64;
    for f in bag_files(path.as_ref())? {
        bytes += std::fs::metadata(&f)?.len();
        bags.push(Bag::open(&f)?);
    }
    let topics = Topics {
        scan: scan.clone(),
        servo: servo.clone(),
        source: ServoSource::Joint(joint.clone()),
        stamps: pingcal_rosbag::clock::Stamps::Auto,
    };
    let (mut beams, mut sum) = (0u64, 0f64);
    let done = read_scans(&bags, &topics, ServoMotion::Auto, &mut |_, line| {
        beams += line.ranges_mm.len() as u64;
        sum += line.ranges_mm.iter().sum::<f64>() + line.servo_deg;
        Ok(())
    })?;
    let t = t0.elapsed().as_secs_f64();
    let mb = bytes as f64 / 1e6;
    println!(
        "{path}: {mb:.0} MB, {} scans, {beams} beams (checksum {sum:.6e}), servo {}, {} pass(es): {t:.2} s ({t:.2} s read), {:.0} MB/s, peak RSS {:.1} MiB",
        done.scans,
        done.motion.name(),
        done.passes,
        mb / t,
        peak_rss_mib().unwrap_or(f64::NAN)
    );
    Ok(())
}
