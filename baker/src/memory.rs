//! The process's memory, for reports: how far a stage of a bake or a generation grew it.

/// Peak resident memory of this process so far (Linux `VmHWM` in /proc/self/status),
/// bytes; None where the system does not report it.
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    Some(line.split_whitespace().nth(1)?.parse::<u64>().ok()? * 1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(target_os = "linux")]
    #[test]
    fn the_peak_grows_with_memory_touched() {
        let before = peak_rss_bytes().expect("VmHWM on Linux");
        // 64 MiB touched page by page: the peak must pass before + most of it.
        let block = vec![1u8; 64 << 20];
        let after = peak_rss_bytes().expect("VmHWM on Linux");
        assert!(block.iter().step_by(4096).all(|&b| b == 1));
        assert!(after >= before && after >= 48 << 20, "peak {before} -> {after} bytes");
    }
}
