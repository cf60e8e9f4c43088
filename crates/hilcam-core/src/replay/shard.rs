//! Which share of a job array's frames this process renders: `--shard K/N`, or the
//! scheduler's environment (Slurm job array, Kubernetes Indexed Job).

use super::{LOG_NAME, ReplayError};

/// Which of the selected frames this process renders: those at positions j ≡ index (mod count).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u64,
    pub count: u64,
}

/// The shard count of a job array: Kubernetes Indexed Jobs give the index only, and a
/// Slurm submission knows only its own subset of the array (e.g. one resubmitted task).
pub const SHARD_COUNT_VAR: &str = "HILCAM_SHARD_COUNT";

impl Shard {
    /// The whole job in one process.
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Parse `K/N`.
    pub fn parse(s: &str) -> Result<Shard, ReplayError> {
        let bad = || ReplayError::BadShard(s.to_string());
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (index, count) = (k.trim().parse::<u64>().map_err(|_| bad())?, n.trim().parse::<u64>().map_err(|_| bad())?);
        if count == 0 || index >= count {
            return Err(bad());
        }
        Ok(Shard { index, count })
    }

    /// The shard of a Slurm job array task or of a Kubernetes Indexed Job pod; `None` when
    /// neither is set. `get` reads a variable (`std::env::var(..).ok()` in the CLI).
    ///
    /// Slurm: with [`SHARD_COUNT_VAR`] set, shard `SLURM_ARRAY_TASK_ID` of it, whatever
    /// subset of the array this submission holds (a resubmitted `--array=5` stays shard 5
    /// of N). Without it, shard `SLURM_ARRAY_TASK_ID` of `SLURM_ARRAY_TASK_COUNT`, which
    /// only names the whole job for an array `0-(N-1)`: an array starting elsewhere (as a
    /// resubmitted task does: `--array=5` has MIN 5, COUNT 1) is refused, not guessed.
    /// Kubernetes: shard `JOB_COMPLETION_INDEX` of [`SHARD_COUNT_VAR`].
    pub fn from_env(get: impl Fn(&str) -> Option<String>) -> Result<Option<Shard>, ReplayError> {
        let num = |var: &'static str, required: bool| -> Result<Option<u64>, ReplayError> {
            match get(var) {
                None if required => Err(ReplayError::Env { var, msg: "not set".into() }),
                None => Ok(None),
                Some(v) => v
                    .trim()
                    .parse::<u64>()
                    .map(Some)
                    .map_err(|_| ReplayError::Env { var, msg: format!("`{v}` is not a non-negative integer") }),
            }
        };
        // Both schedulers' indices set (a Slurm job launched from a pod, a copied
        // environment): each names a shard, and picking one silently would render the
        // wrong frames if they differ.
        if let (Some(slurm), Some(k8s)) = (num("SLURM_ARRAY_TASK_ID", false)?, num("JOB_COMPLETION_INDEX", false)?)
            && slurm != k8s
        {
            return Err(ReplayError::Env {
                var: "SLURM_ARRAY_TASK_ID",
                msg: format!(
                    "is {slurm} but JOB_COMPLETION_INDEX (Kubernetes) is {k8s}: two schedulers name different \
                     shards; unset the one that does not launch this process (or pass --shard K/N)"
                ),
            });
        }
        if let Some(id) = num("SLURM_ARRAY_TASK_ID", false)? {
            if let Some(count) = num(SHARD_COUNT_VAR, false)? {
                if id >= count {
                    return Err(ReplayError::Env {
                        var: "SLURM_ARRAY_TASK_ID",
                        msg: format!("{id} must be below {SHARD_COUNT_VAR} = {count} (the whole array's task count)"),
                    });
                }
                return Ok(Some(Shard { index: id, count }));
            }
            let count = num("SLURM_ARRAY_TASK_COUNT", true)?.unwrap_or(0);
            if count == 0 {
                return Err(ReplayError::Env { var: "SLURM_ARRAY_TASK_COUNT", msg: "is 0".into() });
            }
            let min = num("SLURM_ARRAY_TASK_MIN", false)?.unwrap_or(0);
            if min != 0 {
                return Err(ReplayError::Env {
                    var: "SLURM_ARRAY_TASK_MIN",
                    msg: format!(
                        "is {min}: this array holds tasks {min}.. only (a resubmitted task?), so \
                         SLURM_ARRAY_TASK_COUNT {count} is not the shard count; set {SHARD_COUNT_VAR} to the whole \
                         array's task count (or pass --shard K/N)"
                    ),
                });
            }
            let step = num("SLURM_ARRAY_TASK_STEP", false)?.unwrap_or(1);
            let max = num("SLURM_ARRAY_TASK_MAX", false)?.unwrap_or(count - 1);
            if step != 1 || max != count - 1 {
                return Err(ReplayError::Env {
                    var: "SLURM_ARRAY_TASK_MAX",
                    msg: format!(
                        "is {max} with SLURM_ARRAY_TASK_COUNT {count} and SLURM_ARRAY_TASK_STEP {step}: the array is \
                         not 0-{}; use --array=0-{} or set {SHARD_COUNT_VAR}",
                        count - 1,
                        count - 1
                    ),
                });
            }
            if id >= count {
                return Err(ReplayError::Env {
                    var: "SLURM_ARRAY_TASK_ID",
                    msg: format!("{id} must be below SLURM_ARRAY_TASK_COUNT = {count}"),
                });
            }
            return Ok(Some(Shard { index: id, count }));
        }
        if let Some(index) = num("JOB_COMPLETION_INDEX", false)? {
            let count = num(SHARD_COUNT_VAR, true)?.unwrap_or(0);
            if index >= count {
                return Err(ReplayError::Env {
                    var: "JOB_COMPLETION_INDEX",
                    msg: format!("{index} must be below {SHARD_COUNT_VAR} = {count} (set it to the Job's completions)"),
                });
            }
            return Ok(Some(Shard { index, count }));
        }
        Ok(None)
    }

    /// Metadata log of this shard: `frames.jsonl`, or `frames.shard-K-of-N.jsonl`.
    pub fn log_name(&self) -> String {
        if self.count == 1 {
            LOG_NAME.to_string()
        } else {
            format!("frames.shard-{}-of-{}.jsonl", self.index, self.count)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env<'a>(vars: &'a [(&'a str, &'a str)]) -> impl Fn(&str) -> Option<String> + 'a {
        move |k| vars.iter().find(|(n, _)| *n == k).map(|(_, v)| v.to_string())
    }

    fn err(vars: &[(&str, &str)]) -> String {
        Shard::from_env(env(vars)).unwrap_err().to_string()
    }

    fn shard(index: u64, count: u64) -> Option<Shard> {
        Some(Shard { index, count })
    }

    #[test]
    fn parse_and_log_name() {
        assert_eq!(Shard::parse("3/16").unwrap(), Shard { index: 3, count: 16 });
        for bad in ["16/16", "1/0", "x/2", "3", "-1/4"] {
            assert!(Shard::parse(bad).unwrap_err().to_string().contains("expected K/N"), "{bad}");
        }
        assert_eq!(Shard { index: 1, count: 3 }.log_name(), "frames.shard-1-of-3.jsonl");
        assert_eq!(Shard::ALL.log_name(), "frames.jsonl");
    }

    #[test]
    fn no_scheduler_is_the_whole_job() {
        assert_eq!(Shard::from_env(env(&[])).unwrap(), None);
    }

    /// The variables Slurm sets for task `id` of `sbatch --array=min-max`.
    fn slurm_array(
        id: &'static str,
        min: &'static str,
        max: &'static str,
        count: &'static str,
    ) -> Vec<(&'static str, &'static str)> {
        vec![
            ("SLURM_ARRAY_TASK_ID", id),
            ("SLURM_ARRAY_TASK_MIN", min),
            ("SLURM_ARRAY_TASK_MAX", max),
            ("SLURM_ARRAY_TASK_COUNT", count),
            ("SLURM_ARRAY_TASK_STEP", "1"),
        ]
    }

    #[test]
    fn slurm_whole_array_from_zero() {
        // --array=0-3: task 2 is shard 2 of 4.
        assert_eq!(Shard::from_env(env(&slurm_array("2", "0", "3", "4"))).unwrap(), shard(2, 4));
        // Older Slurm without MIN/MAX/STEP: ID of COUNT.
        let bare = [("SLURM_ARRAY_TASK_ID", "2"), ("SLURM_ARRAY_TASK_COUNT", "3")];
        assert_eq!(Shard::from_env(env(&bare)).unwrap(), shard(2, 3));
        assert_eq!(err(&[("SLURM_ARRAY_TASK_ID", "2")]), "environment variable SLURM_ARRAY_TASK_COUNT: not set");
        let e = err(&[("SLURM_ARRAY_TASK_ID", "a"), ("SLURM_ARRAY_TASK_COUNT", "3")]);
        assert_eq!(e, "environment variable SLURM_ARRAY_TASK_ID: `a` is not a non-negative integer");
        assert_eq!(err(&slurm_array("0", "0", "0", "0")), "environment variable SLURM_ARRAY_TASK_COUNT: is 0");
    }

    #[test]
    fn slurm_resubmitted_task_without_count_is_refused() {
        // `sbatch --array=5` (task 5 of an 8-task array, resubmitted): Slurm says MIN 5,
        // COUNT 1. Reading it as shard 0 of 1 would render the whole trajectory.
        let e = err(&slurm_array("5", "5", "5", "1"));
        assert!(e.starts_with("environment variable SLURM_ARRAY_TASK_MIN: is 5"), "{e}");
        assert!(e.contains("set HILCAM_SHARD_COUNT"), "{e}");
        // --array=4-6 is refused the same way (it used to be read as shards 0..3 of 3).
        assert!(err(&slurm_array("5", "4", "6", "3")).contains("SLURM_ARRAY_TASK_MIN: is 4"));
    }

    #[test]
    fn slurm_gapped_or_strided_array_without_count_is_refused() {
        // --array=0,2,5: MIN 0 but COUNT 3 ≠ MAX + 1.
        let e = err(&slurm_array("2", "0", "5", "3"));
        assert!(e.starts_with("environment variable SLURM_ARRAY_TASK_MAX: is 5 with SLURM_ARRAY_TASK_COUNT 3"), "{e}");
        let mut strided = slurm_array("2", "0", "4", "3");
        strided[4].1 = "2";
        assert!(err(&strided).contains("SLURM_ARRAY_TASK_STEP 2"));
    }

    #[test]
    fn slurm_with_shard_count_uses_the_task_id() {
        let count = ("HILCAM_SHARD_COUNT", "8");
        // The resubmitted task 5 of 8, and any subset (--array=1,5) or stride.
        for vars in [slurm_array("5", "5", "5", "1"), slurm_array("5", "1", "5", "2"), slurm_array("5", "0", "7", "8")]
        {
            let vars = [vars, vec![count]].concat();
            assert_eq!(Shard::from_env(env(&vars)).unwrap(), shard(5, 8), "{vars:?}");
        }
        let e = err(&[slurm_array("8", "8", "8", "1"), vec![count]].concat());
        assert_eq!(
            e,
            "environment variable SLURM_ARRAY_TASK_ID: 8 must be below HILCAM_SHARD_COUNT = 8 (the whole array's task count)"
        );
        let e = err(&[slurm_array("1", "1", "1", "1"), vec![("HILCAM_SHARD_COUNT", "x")]].concat());
        assert_eq!(e, "environment variable HILCAM_SHARD_COUNT: `x` is not a non-negative integer");
    }

    /// Issue 37: disagreeing Slurm and Kubernetes indices were resolved silently (Slurm won).
    #[test]
    fn disagreeing_slurm_and_kubernetes_indices_are_refused_naming_both() {
        let both = |k8s: &'static str| [slurm_array("2", "0", "3", "4"), vec![("JOB_COMPLETION_INDEX", k8s)]].concat();
        let e = err(&both("3"));
        assert!(e.starts_with("environment variable SLURM_ARRAY_TASK_ID: is 2 but JOB_COMPLETION_INDEX"), "{e}");
        assert!(e.contains("(Kubernetes) is 3"), "{e}");
        assert_eq!(Shard::from_env(env(&both("2"))).unwrap(), shard(2, 4), "agreeing indices are one shard");
    }

    #[test]
    fn kubernetes_indexed_job() {
        let k8s = [("JOB_COMPLETION_INDEX", "9"), ("HILCAM_SHARD_COUNT", "10")];
        assert_eq!(Shard::from_env(env(&k8s)).unwrap(), shard(9, 10));
        assert_eq!(err(&[("JOB_COMPLETION_INDEX", "9")]), "environment variable HILCAM_SHARD_COUNT: not set");
        let e = err(&[("JOB_COMPLETION_INDEX", "10"), ("HILCAM_SHARD_COUNT", "10")]);
        assert!(e.starts_with("environment variable JOB_COMPLETION_INDEX: 10 must be below"), "{e}");
    }
}
