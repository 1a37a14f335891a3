//! The process's memory, for reports: how far a stage of a bake or a generation grew it.

/// Peak resident memory of this process so far (Linux `VmHWM` in /proc/self/status),
/// bytes; None where the system does not report it.
pub fn peak_rss_bytes() -> Option<u64> {
    vm_hwm_bytes(&std::fs::read_to_string("/proc/self/status").ok()?)
}

/// The `VmHWM:` line of a /proc status file, which the kernel gives in kB, in bytes.
fn vm_hwm_bytes(status: &str) -> Option<u64> {
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse::<u64>().ok()?.checked_mul(1024)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_status_line_is_read_in_bytes() {
        let status = "Name:\tfabric\nVmPeak:\t  900 kB\nVmHWM:\t   2048 kB\nVmRSS:\t 1024 kB\n";
        assert_eq!(vm_hwm_bytes(status), Some(2048 * 1024));
        assert_eq!(vm_hwm_bytes("VmRSS:\t1024 kB\n"), None);
        assert_eq!(vm_hwm_bytes("VmHWM:\tlots kB\n"), None);
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn the_peak_covers_memory_touched() {
        // 64 MiB touched page by page: whatever ran before, the process's peak is now at
        // least that (a reading of the wrong line, or in kB or pages, would not be).
        let block = vec![1u8; 64 << 20];
        assert!(block.iter().step_by(4096).all(|&b| b == 1));
        let peak = peak_rss_bytes().expect("VmHWM on Linux");
        assert!(peak >= 64 << 20, "peak {peak} bytes");
    }
}
