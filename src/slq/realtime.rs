//! Real-time scheduling for the solver's threads.
//!
//! A receding-horizon controller on a robot runs its solver threads under a real-time
//! policy, so that the rest of the computer's work (logging, the kernel's housekeeping
//! threads) waits for a tick instead of a tick waiting for it: OCS2's MPC interface sets
//! `SCHED_FIFO` on its threads (`SetThreadPriority`), as do ros2's real-time examples.
//! On the 2-vCPU guests legwork is benchmarked on, with both vCPUs busy the guest's own work
//! preempts a solver thread for 1.3-4.5 ms about once every 100 ms to 1 s
//! (benches/results/2026-12-05-xeon-vcpu-stalls.txt), which sets the 99th percentile of
//! the tick time; under `SCHED_FIFO` those ordinary threads wait for the solver.
//!
//! Linux limits real-time threads to 95 % of each second (`sched_rt_runtime_us`): a solver
//! that never sleeps is paused for the rest, so a thread stuck in a loop cannot freeze the
//! machine. A closed loop's solver sleeps between ticks while the plant steps.

/// The `SCHED_FIFO` priorities Linux accepts (1 = lowest, 99 = highest).
pub const REALTIME_PRIORITIES: std::ops::RangeInclusive<i32> = 1..=99;

/// Why a thread's real-time priority could not be set.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RealtimePriorityError {
    #[error("expected a SCHED_FIFO priority in 1..=99, got {0}")]
    OutOfRange(i32),
    #[error("setting SCHED_FIFO priority {priority} failed: {reason} (it needs root, CAP_SYS_NICE or an rtprio limit of at least {priority} in /etc/security/limits.conf)")]
    Refused { priority: i32, reason: String },
    #[error("real-time thread priorities are implemented for Linux only")]
    Unsupported,
}

/// Puts the calling thread under `SCHED_FIFO` at `priority` (1 = lowest, 99 = highest;
/// OCS2's robot examples set 50, its `threadPriority`; a threaded kernel's interrupt
/// handlers run at 50). Any priority runs before every ordinary (`SCHED_OTHER`) thread.
///
/// ```
/// use legwork::slq::{set_realtime_priority, RealtimePriorityError};
/// assert_eq!(set_realtime_priority(0), Err(RealtimePriorityError::OutOfRange(0)));
/// assert_eq!(set_realtime_priority(100), Err(RealtimePriorityError::OutOfRange(100)));
/// ```
pub fn set_realtime_priority(priority: i32) -> Result<(), RealtimePriorityError> {
    if !REALTIME_PRIORITIES.contains(&priority) {
        return Err(RealtimePriorityError::OutOfRange(priority));
    }
    set_fifo(priority)
}

#[cfg(target_os = "linux")]
fn set_fifo(priority: i32) -> Result<(), RealtimePriorityError> {
    let param = libc::sched_param { sched_priority: priority };
    // SAFETY: pthread_self() is the calling thread, alive for the call; `param` is a valid
    // sched_param that outlives it.
    let code = unsafe { libc::pthread_setschedparam(libc::pthread_self(), libc::SCHED_FIFO, &param) };
    if code == 0 {
        Ok(())
    } else {
        Err(RealtimePriorityError::Refused { priority, reason: std::io::Error::from_raw_os_error(code).to_string() })
    }
}

#[cfg(not(target_os = "linux"))]
fn set_fifo(_priority: i32) -> Result<(), RealtimePriorityError> {
    Err(RealtimePriorityError::Unsupported)
}
