//! The CPU and memory this process may use: its CPU affinity, its cgroup's CPU quota and memory
//! limit (cgroup v2, else v1), and Slurm's per-task CPU count, so that a batch inside a Slurm
//! allocation or a container takes its share of the node and not the whole node.

use std::path::{Path, PathBuf};

/// The CPUs and memory available to this process.
#[derive(Clone, Copy, Debug)]
pub struct Resources {
    pub threads: usize,
    pub memory_bytes: u64,
}

/// Threads: the smallest of the affinity mask's CPUs, the cgroup quota (rounded up) and
/// `SLURM_CPUS_PER_TASK`; memory: the cgroup limit, else the machine's memory.
pub fn available() -> Resources {
    let mut threads = affinity_cpus()
        .unwrap_or_else(|| std::thread::available_parallelism().map(|n| n.get()).unwrap_or(1));
    if let Some(quota) = cgroup_cpu_quota() {
        threads = threads.min(quota.ceil().max(1.0) as usize);
    }
    if let Some(n) = std::env::var("SLURM_CPUS_PER_TASK").ok().and_then(|v| v.parse::<usize>().ok())
        && n > 0
    {
        threads = threads.min(n);
    }
    let machine = meminfo_total().unwrap_or(u64::MAX);
    let memory_bytes = cgroup_memory_limit().map_or(machine, |limit| limit.min(machine));
    Resources { threads: threads.max(1), memory_bytes }
}

/// The number of CPUs in this process's affinity mask (`sched_getaffinity`).
fn affinity_cpus() -> Option<usize> {
    // SAFETY: `set` is a plain bit set that `sched_getaffinity` fills in; its size is passed.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return None;
        }
        let n = libc::CPU_COUNT(&set);
        (n > 0).then_some(n as usize)
    }
}

/// This process's cgroup path per controller: `("", path)` for v2, `("cpu,cpuacct", path)` for
/// the v1 hierarchies, from `/proc/self/cgroup`.
fn cgroup_paths() -> Vec<(String, String)> {
    let Ok(text) = std::fs::read_to_string("/proc/self/cgroup") else { return Vec::new() };
    text.lines()
        .filter_map(|line| {
            let mut parts = line.splitn(3, ':');
            let _id = parts.next()?;
            let controllers = parts.next()?.to_string();
            let path = parts.next()?.to_string();
            Some((controllers, path))
        })
        .collect()
}

/// Candidate folders of a controller, innermost first: the process's own cgroup, then each
/// parent (a limit set on a parent applies too; the innermost one found is used).
fn controller_dirs(v1_name: &str) -> Vec<PathBuf> {
    let root = Path::new("/sys/fs/cgroup");
    let mut dirs = Vec::new();
    for (controllers, path) in cgroup_paths() {
        let base = if controllers.is_empty() {
            root.to_path_buf()
        } else if controllers.split(',').any(|c| c == v1_name) {
            root.join(&controllers)
        } else {
            continue;
        };
        let mut rel = PathBuf::from(path.trim_start_matches('/'));
        loop {
            dirs.push(base.join(&rel));
            if !rel.pop() {
                break;
            }
        }
    }
    dirs
}

fn read_trimmed(path: &Path) -> Option<String> {
    std::fs::read_to_string(path).ok().map(|s| s.trim().to_string())
}

/// The CPU quota in CPUs: v2 `cpu.max` ("QUOTA PERIOD" or "max PERIOD"), v1
/// `cpu.cfs_quota_us` / `cpu.cfs_period_us` (-1: none).
fn cgroup_cpu_quota() -> Option<f64> {
    for dir in controller_dirs("cpu") {
        if let Some(text) = read_trimmed(&dir.join("cpu.max")) {
            let mut it = text.split_whitespace();
            let (quota, period) = (it.next()?, it.next()?);
            if quota == "max" {
                continue;
            }
            let (q, p) = (quota.parse::<f64>().ok()?, period.parse::<f64>().ok()?);
            return (p > 0.0).then_some(q / p);
        }
        let quota = read_trimmed(&dir.join("cpu.cfs_quota_us")).and_then(|s| s.parse::<i64>().ok());
        let period =
            read_trimmed(&dir.join("cpu.cfs_period_us")).and_then(|s| s.parse::<i64>().ok());
        if let (Some(q), Some(p)) = (quota, period)
            && q > 0
            && p > 0
        {
            return Some(q as f64 / p as f64);
        }
    }
    None
}

/// The memory limit: v2 `memory.max` ("max": none), v1 `memory.limit_in_bytes` (a huge value:
/// none, which `available` caps at the machine's memory).
fn cgroup_memory_limit() -> Option<u64> {
    for dir in controller_dirs("memory") {
        for file in ["memory.max", "memory.limit_in_bytes"] {
            if let Some(text) = read_trimmed(&dir.join(file))
                && let Ok(bytes) = text.parse::<u64>()
            {
                return Some(bytes);
            }
        }
    }
    None
}

/// `MemTotal` of `/proc/meminfo` in bytes.
fn meminfo_total() -> Option<u64> {
    let text = std::fs::read_to_string("/proc/meminfo").ok()?;
    let line = text.lines().find(|l| l.starts_with("MemTotal:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}

/// Parses a byte count with an optional binary suffix: `512M`, `16G`, `1.5T`, `1000000`.
pub fn parse_bytes(text: &str) -> Result<u64, String> {
    let t = text.trim();
    let (number, unit) = match t.find(|c: char| c.is_ascii_alphabetic()) {
        Some(i) => t.split_at(i),
        None => (t, ""),
    };
    let scale: f64 = match unit.trim_end_matches(['B', 'b', 'i']).to_ascii_uppercase().as_str() {
        "" => 1.0,
        "K" => 1024.0,
        "M" => 1024.0 * 1024.0,
        "G" => 1024.0 * 1024.0 * 1024.0,
        "T" => 1024.0 * 1024.0 * 1024.0 * 1024.0,
        _ => return Err(format!("unknown unit in {text:?} (use K, M, G or T)")),
    };
    match number.trim().parse::<f64>() {
        Ok(n) if n.is_finite() && n > 0.0 => Ok((n * scale) as u64),
        _ => Err(format!("expected a positive size such as 16G, got {text:?}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sizes_parse_with_binary_units() {
        assert_eq!(parse_bytes("1000"), Ok(1000));
        assert_eq!(parse_bytes("2K"), Ok(2048));
        assert_eq!(parse_bytes("1.5GiB"), Ok(3 << 29));
        assert!(parse_bytes("12Q").is_err());
        assert!(parse_bytes("-3G").is_err());
    }

    #[test]
    fn resources_are_positive_and_within_the_machine() {
        let r = available();
        assert!(r.threads >= 1);
        assert!(r.threads <= std::thread::available_parallelism().map_or(usize::MAX, |n| n.get()));
        assert!(r.memory_bytes > 0);
    }
}
