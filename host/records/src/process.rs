//! Which process owns a running roll, and whether it still lives: a roll whose process
//! is gone was interrupted (killed, or the machine lost power).
//!
//! A process is named `HOST:PID:START` (START the kernel's start time of the process, so
//! a PID reused by another process does not count as alive). Only the host that wrote a
//! roll can tell: a roll of another host stays `running` until that host starts again.

/// This process's name.
pub fn this_process() -> String {
    let pid = std::process::id();
    format!(
        "{}:{pid}:{}",
        host_name(),
        start_time(pid).unwrap_or_default()
    )
}

/// Whether the process named `token` is known to have ended. False when it cannot be
/// told (another host, or a system without `/proc`).
pub fn has_ended(token: &str) -> bool {
    let Some((host, pid, start)) = parts(token) else {
        return false;
    };
    let Ok(pid) = pid.parse::<u32>() else {
        return false;
    };
    if host != host_name() || !std::path::Path::new("/proc/self/stat").exists() {
        return false;
    }
    start_time(pid).as_deref() != Some(start)
}

/// Whether the process named `token` ran on this host.
pub fn is_this_host(token: &str) -> bool {
    parts(token).is_some_and(|(host, _, _)| host == host_name())
}

/// A process name's host, PID and start (a host name may hold `:`).
fn parts(token: &str) -> Option<(&str, &str, &str)> {
    let mut parts = token.rsplitn(3, ':');
    let (start, pid) = (parts.next()?, parts.next()?);
    Some((parts.next()?, pid, start))
}

fn host_name() -> String {
    std::fs::read_to_string("/proc/sys/kernel/hostname")
        .ok()
        .or_else(|| std::env::var("HOSTNAME").ok())
        .map(|h| h.trim().to_owned())
        .filter(|h| !h.is_empty())
        .unwrap_or_else(|| "localhost".to_owned())
}

/// Field 22 of `/proc/PID/stat`: when the process started, in clock ticks since boot.
fn start_time(pid: u32) -> Option<String> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).ok()?;
    // The command name (field 2) is in parentheses and may hold spaces: count after it.
    let after = &stat[stat.rfind(')')? + 1..];
    after.split_whitespace().nth(19).map(str::to_owned)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn this_process_lives_and_a_dead_one_has_ended() {
        let me = this_process();
        assert!(!has_ended(&me), "{me}");
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        let start = start_time(pid);
        child.wait().unwrap();
        if let Some(start) = start {
            assert!(has_ended(&format!("{}:{pid}:{start}", host_name())));
        }
        assert!(!has_ended("another-host:1:1"));
        assert!(!has_ended("garbage"));
        assert!(is_this_host(&me));
        assert!(!is_this_host("another-host:1:1"));
        assert!(!is_this_host("garbage"));
    }
}
