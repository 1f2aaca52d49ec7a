//! Which share of the sorted model list this process takes: `--shard I/N`, else Slurm's job
//! array variables, else Kubernetes' `JOB_COMPLETION_INDEX` with `--shards N`, else all of it.

use std::fmt;

/// Share `index` of `count` (0-based): the models whose position in the sorted list is
/// `index` modulo `count`, so that big and small models spread evenly over the shards.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    pub index: u32,
    pub count: u32,
}

impl fmt::Display for Shard {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}", self.index, self.count)
    }
}

impl Shard {
    pub const ALL: Shard = Shard { index: 0, count: 1 };

    /// Whether the model at `position` of the sorted list belongs to this shard.
    pub fn takes(&self, position: usize) -> bool {
        position as u64 % u64::from(self.count) == u64::from(self.index)
    }

    fn new(index: u64, count: u64, source: &str) -> Result<Shard, String> {
        if count == 0 || index >= count || count > u64::from(u32::MAX) {
            return Err(format!("{source}: shard index {index} is not below the count {count}"));
        }
        Ok(Shard { index: index as u32, count: count as u32 })
    }
}

/// Parses `I/N`.
pub fn parse(text: &str) -> Result<Shard, String> {
    let bad = || format!("expected --shard I/N with 0 <= I < N, got {text:?}");
    let (i, n) = text.split_once('/').ok_or_else(bad)?;
    let i = i.trim().parse::<u64>().map_err(|_| bad())?;
    let n = n.trim().parse::<u64>().map_err(|_| bad())?;
    Shard::new(i, n, "--shard")
}

/// The shard from the flags or the environment (`env` looks a variable up, so tests need not
/// change the process's environment).
pub fn resolve(
    flag: Option<&str>,
    shards: Option<u32>,
    env: &dyn Fn(&str) -> Option<String>,
) -> Result<Shard, String> {
    if let Some(text) = flag {
        return parse(text);
    }
    let number = |name: &str| -> Result<Option<u64>, String> {
        match env(name) {
            None => Ok(None),
            Some(v) if v.trim().is_empty() => Ok(None),
            Some(v) => v
                .trim()
                .parse::<u64>()
                .map(Some)
                .map_err(|_| format!("{name}={v:?} is not a whole number")),
        }
    };
    if let Some(id) = number("SLURM_ARRAY_TASK_ID")? {
        let count = number("SLURM_ARRAY_TASK_COUNT")?
            .ok_or("SLURM_ARRAY_TASK_ID is set but SLURM_ARRAY_TASK_COUNT is not")?;
        // `--array=4-10:2` numbers its tasks 4, 6, 8, 10: the share is the position in that run.
        let min = number("SLURM_ARRAY_TASK_MIN")?.unwrap_or(0);
        let step = number("SLURM_ARRAY_TASK_STEP")?.unwrap_or(1).max(1);
        let offset =
            id.checked_sub(min).ok_or("SLURM_ARRAY_TASK_ID is below SLURM_ARRAY_TASK_MIN")?;
        if offset % step != 0 {
            return Err(format!(
                "SLURM_ARRAY_TASK_ID {id} is not on the array's step {step} from {min}; \
                 use --array=0-N (or pass --shard I/N)"
            ));
        }
        return Shard::new(offset / step, count, "Slurm job array");
    }
    if let Some(index) = number("JOB_COMPLETION_INDEX")? {
        let count = shards.ok_or(
            "JOB_COMPLETION_INDEX is set: give the Job's completions as --shards N (or --shard I/N)",
        )?;
        return Shard::new(index, u64::from(count), "JOB_COMPLETION_INDEX");
    }
    match shards {
        Some(_) => Err("--shards N needs JOB_COMPLETION_INDEX in the environment".into()),
        None => Ok(Shard::ALL),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn env_of(pairs: &'static [(&'static str, &'static str)]) -> impl Fn(&str) -> Option<String> {
        move |name| pairs.iter().find(|(k, _)| *k == name).map(|(_, v)| (*v).to_string())
    }

    #[test]
    fn flag_wins_and_is_checked() {
        let env = env_of(&[("SLURM_ARRAY_TASK_ID", "1"), ("SLURM_ARRAY_TASK_COUNT", "2")]);
        assert_eq!(resolve(Some("2/3"), None, &env), Ok(Shard { index: 2, count: 3 }));
        assert!(resolve(Some("3/3"), None, &env).is_err());
        assert!(resolve(Some("1"), None, &env).is_err());
    }

    #[test]
    fn slurm_arrays_count_from_their_minimum_and_step() {
        let env = env_of(&[
            ("SLURM_ARRAY_TASK_ID", "8"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "4"),
            ("SLURM_ARRAY_TASK_STEP", "2"),
        ]);
        assert_eq!(resolve(None, None, &env), Ok(Shard { index: 2, count: 4 }));
        let off_step = env_of(&[
            ("SLURM_ARRAY_TASK_ID", "5"),
            ("SLURM_ARRAY_TASK_COUNT", "4"),
            ("SLURM_ARRAY_TASK_MIN", "4"),
            ("SLURM_ARRAY_TASK_STEP", "2"),
        ]);
        assert!(resolve(None, None, &off_step).is_err());
    }

    #[test]
    fn kubernetes_index_needs_the_count() {
        let env = env_of(&[("JOB_COMPLETION_INDEX", "3")]);
        assert_eq!(resolve(None, Some(5), &env), Ok(Shard { index: 3, count: 5 }));
        assert!(resolve(None, None, &env).is_err());
        assert!(resolve(None, Some(3), &env).is_err());
        assert_eq!(resolve(None, None, &env_of(&[])), Ok(Shard::ALL));
    }

    #[test]
    fn shards_cover_every_position_once() {
        let shards: Vec<Shard> = (0..3).map(|index| Shard { index, count: 3 }).collect();
        for position in 0..20 {
            assert_eq!(shards.iter().filter(|s| s.takes(position)).count(), 1);
        }
    }
}
