//! Trajectory files: CSV of timed poses, for `hilcam send`, offline replay and
//! the demo. Format (documented in `docs/trajectory.md`):
//!
//! ```text
//! # comments and blank lines are ignored
//! time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz[,vx,vy,vz][,wx,wy,wz][,iw,ix,iy,iz][,plx,ply,plz]
//! 0.0,0,0,1000,1,0,0,0,0,0,-1
//! ```
//!
//! Columns may come in any order; `vx,vy,vz`, `wx,wy,wz`, the camera's inertial
//! attitude `iw,ix,iy,iz` and the planet's centre `plx,ply,plz` are optional, as
//! complete groups. Time must strictly increase. [`Trajectory::load`] returns
//! the samples exactly as written (what `hilcam send` puts on the wire, so a
//! receiver's pose gate can be exercised); [`Trajectory::load_gated`] passes
//! every row through the pose gate ([`crate::pose::validate`]), as offline
//! replay does, and names the line of the first pose it refuses.

use crate::pose::Pose;
use crate::pose::validate::{PoseLimits, PoseValidator};
use glam::{DQuat, DVec3};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// One row of a trajectory.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrajectorySample {
    /// Simulation time, s.
    pub time_s: f64,
    /// Target origin in the camera frame, m.
    pub position: DVec3,
    /// Body → camera rotation.
    pub attitude: DQuat,
    /// Unit vector toward the sun, camera frame.
    pub sun_dir: DVec3,
    /// Relative velocity, camera frame, m/s.
    pub velocity: Option<DVec3>,
    /// Angular rate of the body relative to the camera, camera frame, rad/s.
    pub angular_rate: Option<DVec3>,
    /// Camera → inertial rotation (places a star field).
    pub camera_to_inertial: Option<DQuat>,
    /// The scene's planet's centre, camera frame, m (moves its `[planet]`).
    pub planet_centre: Option<DVec3>,
}

impl TrajectorySample {
    /// The pose for this sample, with sequence number `seq`; time rounds to ns.
    pub fn to_pose(&self, seq: u32) -> Pose {
        Pose {
            seq,
            t_ns: (self.time_s * 1e9).round() as u64,
            position: self.position,
            attitude: self.attitude,
            sun_dir: self.sun_dir,
            velocity: self.velocity,
            angular_rate: self.angular_rate,
            camera_to_inertial: self.camera_to_inertial,
            planet_centre: self.planet_centre,
        }
    }
}

/// What went wrong reading a trajectory; line and column are 1-based.
#[derive(Debug, thiserror::Error)]
pub enum TrajectoryError {
    /// The file could not be read or written.
    #[error("{path}: {source}")]
    Io {
        /// File.
        path: PathBuf,
        /// Cause.
        #[source]
        source: std::io::Error,
    },
    /// A content error at a position in the file.
    #[error("{path}:{line}:{column}: {msg}")]
    Parse {
        /// File.
        path: PathBuf,
        /// Line, 1-based.
        line: usize,
        /// Column (field index), 1-based; 0 for whole-line errors.
        column: usize,
        /// What is wrong.
        msg: String,
    },
}

/// The required columns, in the order `save` writes them.
pub const REQUIRED_COLUMNS: [&str; 11] = ["time_s", "px", "py", "pz", "qw", "qx", "qy", "qz", "sx", "sy", "sz"];
/// Optional columns (each group all or nothing): velocity, angular rate, camera → inertial,
/// planet centre.
pub const OPTIONAL_COLUMNS: [&str; 13] =
    ["vx", "vy", "vz", "wx", "wy", "wz", "iw", "ix", "iy", "iz", "plx", "ply", "plz"];
/// (first index, length) of each optional group among all columns.
const OPTIONAL_GROUPS: [(usize, usize); 4] = [(11, 3), (14, 3), (17, 4), (21, 3)];
/// Number of known columns.
const ALL_COLUMNS: usize = REQUIRED_COLUMNS.len() + OPTIONAL_COLUMNS.len();

/// How far from 1 the norm of a row's `iw,ix,iy,iz` may be (as the pose gate's attitude).
const INERTIAL_NORM_TOLERANCE: f64 = 1e-3;

/// Namespace for trajectory file I/O.
pub struct Trajectory;

impl Trajectory {
    /// Reads and parses a trajectory file.
    ///
    /// # Errors
    /// [`TrajectoryError`] naming the file, line and column.
    pub fn load(path: impl AsRef<Path>) -> Result<Vec<TrajectorySample>, TrajectoryError> {
        let path = path.as_ref();
        let text =
            std::fs::read_to_string(path).map_err(|source| TrajectoryError::Io { path: path.to_path_buf(), source })?;
        Self::parse(&text, path)
    }

    /// Parses trajectory text; `path` is used only in error messages.
    ///
    /// # Errors
    /// [`TrajectoryError::Parse`] with line and column.
    pub fn parse(text: &str, path: &Path) -> Result<Vec<TrajectorySample>, TrajectoryError> {
        Ok(Self::parse_rows(text, path)?.into_iter().map(|(_, s)| s).collect())
    }

    /// Reads a trajectory and passes every row through the pose gate, as a live link's
    /// poses are: the same reasons (non-finite, quaternion or sun norm, range, rates),
    /// with the attitude and sun renormalised as the gate returns them.
    ///
    /// # Errors
    /// Parse errors as [`Trajectory::load`]; a refused pose as
    /// [`TrajectoryError::Parse`] naming its line and the reason.
    pub fn load_gated(path: impl AsRef<Path>, limits: &PoseLimits) -> Result<Vec<TrajectorySample>, TrajectoryError> {
        let path = path.as_ref();
        let text =
            std::fs::read_to_string(path).map_err(|source| TrajectoryError::Io { path: path.to_path_buf(), source })?;
        let mut gate = PoseValidator::new(*limits);
        Self::parse_rows(&text, path)?
            .into_iter()
            .enumerate()
            .map(|(k, (line, s))| {
                let pose = s.to_pose(k as u32);
                let ok = gate.check(&pose).map_err(|r| TrajectoryError::Parse {
                    path: path.to_path_buf(),
                    line,
                    column: 0,
                    msg: format!("pose refused: {r} ({})", crate::pose::validate::describe(&pose, r, limits)),
                })?;
                Ok(TrajectorySample { attitude: ok.attitude, sun_dir: ok.sun_dir, ..s })
            })
            .collect()
    }

    /// The samples with their 1-based line numbers.
    fn parse_rows(text: &str, path: &Path) -> Result<Vec<(usize, TrajectorySample)>, TrajectoryError> {
        let err = |line: usize, column: usize, msg: String| TrajectoryError::Parse {
            path: path.to_path_buf(),
            line,
            column,
            msg,
        };
        let mut rows = text
            .lines()
            .enumerate()
            .map(|(i, l)| (i + 1, l.trim()))
            .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'));
        let Some((hline, header)) = rows.next() else {
            return Err(err(1, 0, "empty file: no header line".into()));
        };
        let names: Vec<&str> = header.split(',').map(str::trim).collect();
        let mut col = [usize::MAX; ALL_COLUMNS];
        let all: Vec<&str> = REQUIRED_COLUMNS.iter().chain(&OPTIONAL_COLUMNS).copied().collect();
        for (i, n) in names.iter().enumerate() {
            let Some(k) = all.iter().position(|a| a == n) else {
                return Err(err(hline, i + 1, format!("unknown column `{n}` (expected {})", all.join(","))));
            };
            if col[k] != usize::MAX {
                return Err(err(hline, i + 1, format!("column `{n}` appears twice")));
            }
            col[k] = i;
        }
        for (k, n) in all.iter().enumerate().take(REQUIRED_COLUMNS.len()) {
            if col[k] == usize::MAX {
                return Err(err(hline, 0, format!("missing required column `{n}`")));
            }
        }
        let has = |k: usize| col[k] != usize::MAX;
        for (t, n) in OPTIONAL_GROUPS {
            if (t..t + n).any(has) && !(t..t + n).all(has) {
                return Err(err(
                    hline,
                    0,
                    format!("optional columns `{}` must come as a complete group", all[t..t + n].join(",")),
                ));
            }
        }
        let mut out: Vec<(usize, TrajectorySample)> = Vec::new();
        for (line, text) in rows {
            let fields: Vec<&str> = text.split(',').map(str::trim).collect();
            if fields.len() != names.len() {
                return Err(err(line, 0, format!("{} fields, header has {}", fields.len(), names.len())));
            }
            let mut v = [0.0f64; ALL_COLUMNS];
            for (k, slot) in v.iter_mut().enumerate() {
                if !has(k) {
                    continue;
                }
                let f = fields[col[k]];
                *slot = f
                    .parse::<f64>()
                    .ok()
                    .filter(|x| x.is_finite())
                    .ok_or_else(|| err(line, col[k] + 1, format!("`{}`: `{f}` is not a finite number", all[k])))?;
            }
            if let Some((_, prev)) = out.last().filter(|(_, p)| v[0] <= p.time_s) {
                return Err(err(
                    line,
                    col[0] + 1,
                    format!("time_s {} does not increase (previous {})", v[0], prev.time_s),
                ));
            }
            if v[0] < 0.0 {
                return Err(err(line, col[0] + 1, "time_s is negative".into()));
            }
            let tri = |k: usize| DVec3::new(v[k], v[k + 1], v[k + 2]);
            let inertial_norm = (v[17] * v[17] + v[18] * v[18] + v[19] * v[19] + v[20] * v[20]).sqrt();
            if has(17) && (inertial_norm - 1.0).abs() > INERTIAL_NORM_TOLERANCE {
                return Err(err(
                    line,
                    col[17] + 1,
                    format!("`iw,ix,iy,iz`: norm {inertial_norm}, must be within {INERTIAL_NORM_TOLERANCE:e} of 1"),
                ));
            }
            out.push((
                line,
                TrajectorySample {
                    time_s: v[0],
                    position: tri(1),
                    attitude: DQuat::from_xyzw(v[5], v[6], v[7], v[4]),
                    sun_dir: tri(8),
                    velocity: has(11).then(|| tri(11)),
                    angular_rate: has(14).then(|| tri(14)),
                    camera_to_inertial: has(17).then(|| DQuat::from_xyzw(v[18], v[19], v[20], v[17])),
                    planet_centre: has(21).then(|| tri(21)),
                },
            ));
        }
        if out.is_empty() {
            return Err(err(hline, 0, "no samples after the header".into()));
        }
        Ok(out)
    }

    /// Formats samples as CSV (shortest round-tripping decimal for each f64).
    /// Optional triples are written if the first sample has them.
    ///
    /// # Panics
    /// If later samples disagree with the first about optional triples.
    pub fn to_csv(samples: &[TrajectorySample]) -> String {
        let has_v = samples.first().is_some_and(|s| s.velocity.is_some());
        let has_w = samples.first().is_some_and(|s| s.angular_rate.is_some());
        let has_i = samples.first().is_some_and(|s| s.camera_to_inertial.is_some());
        let has_p = samples.first().is_some_and(|s| s.planet_centre.is_some());
        let mut s = REQUIRED_COLUMNS.join(",");
        if has_v {
            s.push_str(",vx,vy,vz");
        }
        if has_w {
            s.push_str(",wx,wy,wz");
        }
        if has_i {
            s.push_str(",iw,ix,iy,iz");
        }
        if has_p {
            s.push_str(",plx,ply,plz");
        }
        s.push('\n');
        for x in samples {
            let q = x.attitude;
            let mut vals = vec![x.time_s];
            vals.extend(x.position.to_array());
            vals.extend([q.w, q.x, q.y, q.z]);
            vals.extend(x.sun_dir.to_array());
            assert_eq!(x.velocity.is_some(), has_v, "velocity present in some samples only");
            assert_eq!(x.angular_rate.is_some(), has_w, "rate present in some samples only");
            vals.extend(x.velocity.map(|v| v.to_array()).into_iter().flatten());
            vals.extend(x.angular_rate.map(|v| v.to_array()).into_iter().flatten());
            assert_eq!(x.camera_to_inertial.is_some(), has_i, "inertial attitude present in some samples only");
            vals.extend(x.camera_to_inertial.map(|q| [q.w, q.x, q.y, q.z]).into_iter().flatten());
            assert_eq!(x.planet_centre.is_some(), has_p, "planet centre present in some samples only");
            vals.extend(x.planet_centre.map(|c| c.to_array()).into_iter().flatten());
            for (i, v) in vals.iter().enumerate() {
                let _ = write!(s, "{}{v:?}", if i == 0 { "" } else { "," });
            }
            s.push('\n');
        }
        s
    }

    /// Writes samples to `path` as CSV.
    ///
    /// # Errors
    /// [`TrajectoryError::Io`] naming the file.
    pub fn save(path: impl AsRef<Path>, samples: &[TrajectorySample]) -> Result<(), TrajectoryError> {
        let path = path.as_ref();
        std::fs::write(path, Self::to_csv(samples))
            .map_err(|source| TrajectoryError::Io { path: path.to_path_buf(), source })
    }

    /// Index of the last sample with `time_s <= t` (zero-order hold), or `None`
    /// before the first sample. Samples must be sorted (as `load` returns them).
    pub fn index_at(samples: &[TrajectorySample], t: f64) -> Option<usize> {
        samples.partition_point(|s| s.time_s <= t).checked_sub(1)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn errors_name_file_line_and_column() {
        let text = "# c\ntime_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz\n0,0,0,5,1,0,0,0,0,0,-1\n1,0,0,x,1,0,0,0,0,0,-1\n";
        let e = Trajectory::parse(text, Path::new("t.csv")).unwrap_err().to_string();
        assert_eq!(e, "t.csv:4:4: `pz`: `x` is not a finite number");
        let text = "time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz\n1,0,0,5,1,0,0,0,0,0,-1\n1,0,0,5,1,0,0,0,0,0,-1\n";
        let e = Trajectory::parse(text, Path::new("t.csv")).unwrap_err().to_string();
        assert!(e.starts_with("t.csv:3:1: time_s 1 does not increase"), "{e}");
        let e = Trajectory::parse("time_s,px,py\n", Path::new("t.csv")).unwrap_err().to_string();
        assert_eq!(e, "t.csv:1:0: missing required column `pz`");
        let e =
            Trajectory::parse("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,vx\n", Path::new("t.csv")).unwrap_err().to_string();
        assert!(e.contains("complete group"), "{e}");
    }

    #[test]
    fn inertial_attitude_columns_round_trip_and_are_checked() {
        let text = "time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,iw,ix,iy,iz\n0,0,0,5,1,0,0,0,0,0,-1,0.6,0,0.8,0\n";
        let s = Trajectory::parse(text, Path::new("t.csv")).unwrap();
        assert_eq!(s[0].camera_to_inertial, Some(DQuat::from_xyzw(0.0, 0.8, 0.0, 0.6)));
        assert_eq!(s[0].to_pose(0).camera_to_inertial, s[0].camera_to_inertial);
        assert_eq!(Trajectory::parse(&Trajectory::to_csv(&s), Path::new("t.csv")).unwrap(), s);
        let bad = text.replace(",0.6,0,0.8,0", ",0.7,0,0.8,0");
        let e = Trajectory::parse(&bad, Path::new("t.csv")).unwrap_err().to_string();
        assert!(e.starts_with("t.csv:2:12: `iw,ix,iy,iz`: norm"), "{e}");
        let e = Trajectory::parse("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,iw,ix\n", Path::new("t.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`iw,ix,iy,iz` must come as a complete group"), "{e}");
    }

    #[test]
    fn planet_centre_columns_round_trip_and_come_as_a_group() {
        let text = "time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,plx,ply,plz\n0,0,0,5,1,0,0,0,0,0,-1,1e3,-2.5e7,1.5e11\n";
        let s = Trajectory::parse(text, Path::new("t.csv")).unwrap();
        assert_eq!(s[0].planet_centre, Some(DVec3::new(1e3, -2.5e7, 1.5e11)));
        assert_eq!(s[0].to_pose(3).planet_centre, s[0].planet_centre);
        assert_eq!(Trajectory::parse(&Trajectory::to_csv(&s), Path::new("t.csv")).unwrap(), s);
        let e = Trajectory::parse(&text.replace(",1e3,", ",nan,"), Path::new("t.csv")).unwrap_err().to_string();
        assert_eq!(e, "t.csv:2:12: `plx`: `nan` is not a finite number");
        let e = Trajectory::parse("time_s,px,py,pz,qw,qx,qy,qz,sx,sy,sz,plx,plz\n", Path::new("t.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("`plx,ply,plz` must come as a complete group"), "{e}");
    }

    #[test]
    fn columns_in_any_order_and_hold_lookup() {
        let text = "sz,sy,sx,qz,qy,qx,qw,pz,py,px,time_s\n-1,0,0,0,0,0,1,7,2,1,0.5\n-1,0,0,0,0,0,1,8,2,1,1.5\n";
        let s = Trajectory::parse(text, Path::new("x")).unwrap();
        assert_eq!(s[0].position, DVec3::new(1.0, 2.0, 7.0));
        assert_eq!(s[1].time_s, 1.5);
        assert_eq!(Trajectory::index_at(&s, 0.4), None);
        assert_eq!(Trajectory::index_at(&s, 0.5), Some(0));
        assert_eq!(Trajectory::index_at(&s, 1.49), Some(0));
        assert_eq!(Trajectory::index_at(&s, 99.0), Some(1));
    }
}
