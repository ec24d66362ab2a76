//! Holding the CPUs awake: a PM QoS request on `/dev/cpu_dma_latency`.
//!
//! A thread that blocks on a socket and is woken by a datagram pays for
//! whatever its CPU did while it slept. An idle CPU in a deep sleep state,
//! or an idle vCPU halted in its hypervisor, takes tens of microseconds to
//! come back; a servo cycle made of request/answer hand-overs between two
//! processes (a host and an emulator, each on its own CPU) pays that once
//! per hand-over. On the 2-vCPU VM this project is built on, a UDP round
//! trip between two processes on different vCPUs took 104-159 us (p50)
//! against 17-38 us on one vCPU; the dVRK's SEQ_R_BC_W cycle through the
//! emulator (16 hand-overs) split into two modes, 236 and 751 us, by
//! where the scheduler placed the two threads (BENCHMARKS.md, issue 29).
//!
//! Linux's answer is the CPU latency QoS interface
//! (Documentation/power/pm_qos_interface.rst): a process opens
//! `/dev/cpu_dma_latency`, writes the latency it can accept as a 32-bit
//! integer in microseconds, and the request holds for as long as that
//! file stays open. With 0, the idle governor keeps every CPU in its
//! polling state (on a KVM guest the haltpoll governor polls instead of
//! halting), so a wake-up costs a cache line, not a trip through the
//! hypervisor. Real-time Linux tools do the same (cyclictest holds 0 by
//! default). The price is idle CPUs that spin instead of sleeping, for as
//! long as the holder runs: meant for a robot's controller and for
//! measurements, not for a laptop on battery.
//!
//! The device is root's (mode 0600) on most systems: without permission
//! the hold is not taken and [`CpuLatencyHold::take`] says why, which
//! callers report and carry on.

use std::fs::File;
use std::io::Write;
use std::path::{Path, PathBuf};

/// Where Linux takes CPU latency requests.
pub const CPU_DMA_LATENCY: &str = "/dev/cpu_dma_latency";

/// The largest latency a request may name (the kernel takes an `s32`
/// of microseconds; anything above about 2000 s asks for nothing).
pub const MAX_LATENCY_US: u32 = i32::MAX as u32;

/// A held CPU latency request: released when dropped (the kernel drops
/// the request when its file is closed, so a crash releases it too).
#[derive(Debug)]
pub struct CpuLatencyHold {
    /// The open device: the request lasts as long as this does.
    _request: File,
    latency_us: u32,
    path: PathBuf,
}

/// Why a request could not be held.
#[derive(Debug, thiserror::Error)]
pub enum CpuLatencyError {
    /// The latency does not fit the kernel's signed 32-bit microseconds.
    #[error("a CPU latency of {0} us is out of range (0 to {MAX_LATENCY_US} us)")]
    OutOfRange(u64),
    /// Opening or writing the device failed (no permission, no such
    /// device on this kernel or system).
    #[error("cannot hold a CPU latency request on {path}: {source}")]
    Device {
        /// The device tried.
        path: PathBuf,
        /// What the system said.
        source: std::io::Error,
    },
}

impl CpuLatencyHold {
    /// Ask the kernel to keep every CPU able to wake within `latency_us`
    /// microseconds (0: never sleep deeper than polling), through
    /// [`CPU_DMA_LATENCY`].
    pub fn take(latency_us: u64) -> Result<Self, CpuLatencyError> {
        Self::take_at(Path::new(CPU_DMA_LATENCY), latency_us)
    }

    /// [`CpuLatencyHold::take`] through the device at `path` (tests use
    /// a plain file: the request is the 4 bytes written to it).
    pub fn take_at(path: &Path, latency_us: u64) -> Result<Self, CpuLatencyError> {
        let request =
            i32::try_from(latency_us).map_err(|_| CpuLatencyError::OutOfRange(latency_us))?;
        let device = |source| CpuLatencyError::Device {
            path: path.to_path_buf(),
            source,
        };
        let mut file = std::fs::OpenOptions::new()
            .write(true)
            .open(path)
            .map_err(device)?;
        // The kernel reads one native-endian s32 (it also takes a hex
        // string, which we do not use).
        file.write_all(&request.to_ne_bytes()).map_err(device)?;
        Ok(Self {
            _request: file,
            latency_us: request.unsigned_abs(),
            path: path.to_path_buf(),
        })
    }

    /// The latency held, in microseconds.
    pub fn latency_us(&self) -> u32 {
        self.latency_us
    }

    /// One line for a program's banner.
    pub fn describe(&self) -> String {
        format!(
            "holding CPU wake-up latency at {} us ({}): idle CPUs poll instead of sleeping \
             while this runs",
            self.latency_us,
            self.path.display()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_request_is_one_native_s32_held_while_open() {
        let dir = std::env::temp_dir().join(format!("firelink-cpu-latency-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("cpu_dma_latency");
        std::fs::write(&path, b"").unwrap();
        let hold = CpuLatencyHold::take_at(&path, 25).unwrap();
        assert_eq!(hold.latency_us(), 25);
        assert_eq!(std::fs::read(&path).unwrap(), 25i32.to_ne_bytes());
        assert!(hold.describe().contains("at 25 us"), "{}", hold.describe());
        drop(hold);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn out_of_range_and_missing_devices_are_named() {
        let e = CpuLatencyHold::take_at(Path::new("/nonexistent/x"), 1 << 40).unwrap_err();
        assert!(e.to_string().contains("out of range"), "{e}");
        let e = CpuLatencyHold::take_at(Path::new("/nonexistent/cpu_dma_latency"), 0).unwrap_err();
        let text = e.to_string();
        assert!(text.contains("/nonexistent/cpu_dma_latency"), "{text}");
    }
}
