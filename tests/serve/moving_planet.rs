//! A planet moved per pose (issue 38): over the serial link and from a served trajectory
//! into `hilcam serve`, where its disc lands where the pinhole puts its centre; a planet
//! the gate refuses and a corrupted planet block are counted, never rendered; a trajectory's `plx,ply,plz` replayed offline
//! gives the bytes of `hilcam render --planet` and of a scene whose `[planet]` sits there.

use crate::serve_common;
use glam::DVec3;
use hilcam_core::link::send::{MessageWriter, SerialWriter};
use hilcam_core::pose::Message;
use hilcam_core::pose::serial::encode_frame;
use hilcam_core::serve::config::{GovernorConfig, InputConfig, SerialInput, TrajectoryInput, TriggerConfig};
use serialport::SerialPort;
use serve_common::*;
use std::io::Write;
use std::time::{Duration, Instant};

/// 96² camera, f = 200 px; the 1 m sphere target and a 30 m planet (`[planet]` 1 km away,
/// seen at (28, 28) px where nothing else is; no frame below shows it there: every pose
/// moves it).
const W: usize = 96;
const F_PX: f64 = 200.0;
const PLANET: &str = "[planet]\nradius_m = 30.0\nalbedo = 0.4\ncenter_m = [-100.0, -100.0, 1000.0]\n";

/// Radiance-weighted centroid (continuous pixel coordinates) and sum of the pixels within
/// `r` px of `(cx, cy)`.
fn centroid_near(img: &[f32], (cx, cy): (f64, f64), r: f64) -> (f64, f64, f64) {
    let (mut sx, mut sy, mut s) = (0.0, 0.0, 0.0);
    for (i, &v) in img.iter().enumerate() {
        let (x, y) = ((i % W) as f64 + 0.5, (i / W) as f64 + 0.5);
        if (x - cx).hypot(y - cy) <= r {
            sx += x * v as f64;
            sy += y * v as f64;
            s += v as f64;
        }
    }
    (sx / s, sy / s, s)
}

/// The same sums over the analytic image: each pixel the mean of a 16 × 16 grid of
/// pinhole rays over its area, each ray's radiance from a textbook ray–sphere hit on the
/// Lambert sphere (radius 30 m, albedo 0.4, E = 593.1 W/m²).
fn analytic_near(c: DVec3, sun: DVec3, (cx, cy): (f64, f64), r: f64) -> (f64, f64, f64) {
    let n = 16;
    let mut img = vec![0.0f32; W * W];
    for (i, v) in img.iter_mut().enumerate() {
        let (col, row) = ((i % W) as f64, (i / W) as f64);
        if (col + 0.5 - cx).hypot(row + 0.5 - cy) > r {
            continue;
        }
        let mut sum = 0.0;
        for a in 0..n {
            for b in 0..n {
                let x = col + (a as f64 + 0.5) / n as f64 - W as f64 / 2.0;
                let y = row + (b as f64 + 0.5) / n as f64 - W as f64 / 2.0;
                let d = DVec3::new(x / F_PX, y / F_PX, 1.0).normalize();
                let (tca, r2) = (c.dot(d), 30.0f64 * 30.0);
                let h2 = c.length_squared() - tca * tca;
                if tca > 0.0 && h2 <= r2 {
                    let m = (d * (tca - (r2 - h2).sqrt()) - c) / 30.0;
                    sum += 0.4 * 593.1 * m.dot(sun).max(0.0) / std::f64::consts::PI;
                }
            }
        }
        *v = (sum / (n * n) as f64) as f32;
    }
    centroid_near(&img, (cx, cy), r)
}

fn pinhole(c: DVec3) -> (f64, f64) {
    (W as f64 / 2.0 + F_PX * c.x / c.z, W as f64 / 2.0 + F_PX * c.y / c.z)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_planet_sent_over_serial_lands_where_the_pinhole_puts_it_and_bad_planets_are_counted() {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let dir = tempfile::tempdir().unwrap();
    let (master, slave) = serialport::TTYPort::pair().unwrap();
    let input = InputConfig::Serial(SerialInput { device: slave.name().unwrap(), baud: 921_600 });
    let scene = sphere_scene_with(dir.path(), W as u32, 16, PLANET);
    let mut cfg = config(scene, input, TriggerConfig::default(), GovernorConfig::default());
    cfg.metrics.listen = Some("127.0.0.1:0".parse().unwrap());
    let server = start(cfg, None).await;
    let mut reader = Reader::subscribed(&server.info).await;

    let target = DVec3::new(0.8, -0.5, 10.0); // projects at (64, 38), 20 px radius
    let mut w = SerialWriter::new(master, "test pty");
    // Two planet places 14 px (disc radius 30 m / 400 m · 200 = 15 px) from the target's disc.
    let places = [DVec3::new(-56.0, 56.0, 400.0), DVec3::new(-40.0, 60.0, 420.0)];
    for (k, c) in places.iter().enumerate() {
        // The sun along the line of sight to the planet: its lit disc is symmetric about
        // that line.
        let mut p = pose(k as u32 + 1, target, -*c);
        p.planet_centre = Some(*c);
        w.send(&Message::Pose(p)).unwrap();
        let f = reader.next().await;
        assert_eq!(f.meta.pose_seq, k as u32 + 1);
        let want = pinhole(*c);
        let (x, y, s) = centroid_near(radiance(&f), want, 18.0);
        assert!(s > 0.0, "no planet near {want:?}");
        // Sub-pixel at the pinhole projection of the centre (the gnomonic projection
        // stretches the 0.075 rad disc outward by ~f·α²·tanθ ≈ 0.23 px) …
        assert!(
            (x - want.0).abs() < 0.5 && (y - want.1).abs() < 0.5,
            "planet {k}: centroid ({x:.3}, {y:.3}) vs pinhole ({:.3}, {:.3})",
            want.0,
            want.1
        );
        // … and where the analytic image's centroid is, with its flux.
        let (ax, ay, a) = analytic_near(*c, -c.normalize(), want, 18.0);
        println!(
            "planet {k}: centroid − pinhole ({:.3}, {:.3}) px, − analytic ({:.4}, {:.4}) px, flux/analytic {:.5}",
            x - want.0,
            y - want.1,
            x - ax,
            y - ay,
            s / a
        );
        assert!(
            (x - ax).abs() < 0.02 && (y - ay).abs() < 0.02 && (s / a - 1.0).abs() < 0.005,
            "planet {k}: ({x:.4}, {y:.4}, {s:.1}) vs analytic ({ax:.4}, {ay:.4}, {a:.1})"
        );
        // The scene's own place is empty: the pose moved the planet.
        let (_, _, there) = centroid_near(radiance(&f), (28.0, 28.0), 8.0);
        assert!(there == 0.0, "something at the scene's [planet] place: {there}");
    }

    // A pose without a planet centre: the scene's [planet] where the table puts it.
    w.send(&Message::Pose(pose(3, target, DVec3::new(0.1, 0.1, -1.0)))).unwrap();
    let f = reader.next().await;
    let (_, _, there) = centroid_near(radiance(&f), (28.0, 28.0), 8.0);
    assert!(there > 0.0, "the scene's [planet] is missing");

    // Refused by the gate (counted `planet`, no frame): the camera inside the sphere.
    let mut inside = pose(4, target, DVec3::NEG_Z);
    inside.planet_centre = Some(DVec3::new(0.0, 0.0, 20.0));
    w.send(&Message::Pose(inside)).unwrap();
    // A planet block corrupted on the line (one byte of plx flipped): a CRC failure, no frame.
    let mut good = pose(5, target, -places[0]);
    good.planet_centre = Some(places[0]);
    let mut bytes = encode_frame(&Message::Pose(good));
    let plx_at = 18 + 84 + 3; // header, base payload, a byte inside plx
    bytes[plx_at] ^= 0x10;
    // Keep the pty's master open until both are counted: closing it hangs up the line, and
    // the receiver may lose what it had not read yet.
    let mut master = w.into_inner();
    master.write_all(&bytes).unwrap();

    // Both counted (a bounded poll of the metrics: the receiver runs on its own time).
    let want = ["hilcam_input_rejected_total{reason=\"planet\"} 1", "hilcam_input_crc_failures_total 1"];
    let deadline = Instant::now() + PATIENCE;
    loop {
        let mut s = tokio::net::TcpStream::connect(server.info.metrics.expect("metrics listener")).await.unwrap();
        s.write_all(b"GET /metrics HTTP/1.1\r\nHost: x\r\n\r\n").await.unwrap();
        let mut text = String::new();
        s.read_to_string(&mut text).await.unwrap();
        if want.iter().all(|w| text.lines().any(|l| l == *w)) {
            break;
        }
        assert!(Instant::now() < deadline, "not counted within {PATIENCE:?}: {text}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let report = server.finish().await;
    assert_eq!((report.poses_accepted, report.poses_rejected, report.scheduler.frames), (3, 1, 3));
    drop((master, slave));
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_served_trajectory_moves_the_planet_and_counts_a_planet_row_the_gate_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let csv = dir.path().join("t.csv");
    let places = [DVec3::new(-56.0, 56.0, 400.0), DVec3::new(0.0, 0.0, 5.0), DVec3::new(-40.0, 60.0, 420.0)];
    let mut text = String::from("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,plx,ply,plz\n");
    for (k, c) in places.iter().enumerate() {
        let s = -c.normalize();
        text.push_str(&format!(
            "{},0.8,-0.5,10,1,0,0,0,{},{},{},{},{},{}\n",
            k as f64 * 0.3,
            s.x,
            s.y,
            s.z,
            c.x,
            c.y,
            c.z
        ));
    }
    std::fs::write(&csv, text).unwrap();
    let input = InputConfig::Trajectory(TrajectoryInput { file: csv, speed: 1.0 });
    let scene = sphere_scene_with(dir.path(), W as u32, 4, PLANET);
    let server = start(config(scene, input, TriggerConfig::default(), GovernorConfig::default()), None).await;
    let mut reader = Reader::connect(server.info.stream).await;
    // Rows 0 and 2 render with their planets; row 1 (the camera inside the planet) does not.
    for k in [0usize, 2] {
        let f = reader.next().await;
        assert_eq!(f.meta.pose_seq, k as u32);
        let want = pinhole(places[k]);
        let (x, y, _) = centroid_near(radiance(&f), want, 18.0);
        assert!((x - want.0).abs() < 0.5 && (y - want.1).abs() < 0.5, "row {k}: ({x:.3}, {y:.3}) vs {want:?}");
    }
    let report = server.finish().await;
    assert_eq!((report.poses_accepted, report.poses_rejected, report.scheduler.frames), (2, 1, 2));
}

#[test]
fn a_replayed_planet_row_is_hilcam_render_with_that_planet_and_a_scene_with_it_there() {
    let dir = tempfile::tempdir().unwrap();
    let sphere = |name: &str, centre: &str| {
        let p = sphere_scene_with(
            dir.path(),
            48,
            2,
            &format!("[planet]\nradius_m = 30.0\nalbedo = 0.4\ncenter_m = [{centre}]\n"),
        );
        let to = dir.path().join(name);
        std::fs::rename(p, &to).unwrap();
        to
    };
    let moved = sphere("moved.toml", "0.0, 0.0, 1000.0");
    let rows = [("0,0.3,0,10,1,0,0,0,0.6,0,-0.8", "-56,40,400"), ("1,0.3,0.1,10,1,0,0,0,0.6,0,-0.8", "-50,45,410")];
    let csv = dir.path().join("t.csv");
    let body: String = rows.iter().map(|(p, c)| format!("{p},{c}\n")).collect();
    std::fs::write(&csv, format!("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,plx,ply,plz\n{body}")).unwrap();
    let out = dir.path().join("out");
    let os = |s: &str| std::ffi::OsString::from(s);
    let (ok, err) = hilcam(&[
        &os("replay"),
        &os("--trajectory"),
        csv.as_os_str(),
        &os("--scene"),
        moved.as_os_str(),
        &os("--format"),
        &os("pfm"),
        &os("--out"),
        out.as_os_str(),
    ]);
    assert!(ok, "{err}");
    for (k, (row, centre)) in rows.iter().enumerate() {
        let pose = row.split_once(',').unwrap().1;
        let replayed = std::fs::read(out.join(format!("frame_{k:010}.pfm"))).unwrap();
        let render = |scene: &std::path::Path, planet: Option<&str>, name: &str| {
            let file = dir.path().join(name);
            let mut args = vec![os("render"), scene.as_os_str().to_owned(), os("--pose"), os(pose)];
            if let Some(c) = planet {
                args.extend([os("--planet"), os(c)]);
            }
            args.extend([os("--frame"), os(&k.to_string()), os("--out"), file.clone().into_os_string()]);
            let (ok, err) = hilcam(&args.iter().map(|a| a.as_os_str()).collect::<Vec<_>>());
            assert!(ok, "{err}");
            std::fs::read(file).unwrap()
        };
        let with_flag = render(&moved, Some(centre), &format!("flag_{k}.pfm"));
        assert!(replayed == with_flag, "frame {k}: replay differs from `hilcam render --planet {centre}`");
        let there = sphere(&format!("there_{k}.toml"), centre);
        let fixed = render(&there, None, &format!("fixed_{k}.pfm"));
        assert!(replayed == fixed, "frame {k}: replay differs from a scene whose [planet] is at {centre}");
        let still = render(&moved, None, &format!("still_{k}.pfm"));
        assert!(replayed != still, "frame {k}: the planet did not move");
    }
    // Refused with the file and line: a planet row on a scene without `[planet]`, a planet
    // around the camera; `hilcam send` over CAN refuses a trajectory that moves a planet.
    let bare = dir.path().join("bare.toml");
    std::fs::rename(sphere_scene(dir.path(), 48, 2), &bare).unwrap();
    let (ok, err) = hilcam(&[
        &os("replay"),
        &os("--trajectory"),
        csv.as_os_str(),
        &os("--scene"),
        bare.as_os_str(),
        &os("--out"),
        dir.path().join("o2").as_os_str(),
    ]);
    assert!(
        !ok && err.contains("t.csv:2:0: pose refused: planet centre refused") && err.contains("no [planet]"),
        "{err}"
    );
    let inside = dir.path().join("inside.csv");
    std::fs::write(&inside, "time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,plx,ply,plz\n0,0,0,10,1,0,0,0,0,0,-1,0,0,29\n")
        .unwrap();
    let (ok, err) = hilcam(&[
        &os("replay"),
        &os("--trajectory"),
        inside.as_os_str(),
        &os("--scene"),
        moved.as_os_str(),
        &os("--out"),
        dir.path().join("o3").as_os_str(),
    ]);
    assert!(!ok && err.contains("inside.csv:2:0:") && err.contains("the camera is inside it"), "{err}");
}
