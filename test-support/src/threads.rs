//! The process's threads, for tests that check a reconstruction leaves none of its workers
//! running (Linux: `/proc/self/task`).

/// The kernel's flag for a task in its exit path (PF_EXITING, `include/linux/sched.h`).
const PF_EXITING: u64 = 0x4;

/// Names of this process's threads whose name starts with `prefix` and that still run: a
/// thread already in the kernel's exit path is left out. A joined thread can stay listed in
/// `/proc/self/task` for a moment after `pthread_join` returns (the kernel wakes the joiner
/// before it unlists the thread), but by then it runs no user code, which is what the callers
/// check; a thread that was not joined is still in user code when checked at once.
#[cfg(target_os = "linux")]
pub fn running_threads_named(prefix: &str) -> Vec<String> {
    let mut names = Vec::new();
    let tasks = std::fs::read_dir("/proc/self/task").expect("/proc/self/task is readable");
    for task in tasks.flatten() {
        let Ok(name) = std::fs::read_to_string(task.path().join("comm")) else {
            continue;
        };
        if !name.starts_with(prefix) {
            continue;
        }
        // /proc/<tid>/stat: "tid (comm) state ppid pgrp session tty tpgid flags ...".
        let Ok(stat) = std::fs::read_to_string(task.path().join("stat")) else {
            continue; // gone since the directory was read
        };
        let after_comm = stat.rsplit_once(')').map_or("", |(_, rest)| rest);
        let flags: u64 = after_comm
            .split_whitespace()
            .nth(6)
            .and_then(|f| f.parse().ok())
            .unwrap_or(0);
        if flags & PF_EXITING == 0 {
            names.push(name.trim().to_string());
        }
    }
    names
}
