//! What a run may leave behind, looked for after `lopd run` stopped: processes of the run
//! (anything whose arguments name its service prefix), iceoryx2 services under the prefix, and
//! iceoryx2 nodes — alive or dead — of any process the run involved (`lopd run`, its children
//! of every generation, the `lopd ctl` processes, and this bench, whose own nodes are dropped
//! first). Nodes carry no prefix, so they are matched by the process that created them; other
//! users' nodes on the machine are not looked at.

use std::collections::BTreeSet;
use std::time::{Duration, Instant};

use iceoryx2::node::NodeView;
use iceoryx2::prelude::*;
use serde::Serialize;

use super::memory::cmdline;
use super::report::{check, Check, Evidence};

/// One node left behind.
#[derive(Debug, Clone, Serialize)]
pub struct LeftNode {
    /// The process that created it.
    pub pid: u32,
    /// Its name.
    pub name: String,
    /// `alive`, `dead`, `inaccessible` or `undefined`.
    pub state: &'static str,
}

/// What was found.
#[derive(Debug, Clone, Default, Serialize)]
pub struct Leftovers {
    /// Processes whose arguments name the prefix: pid and command line.
    pub processes: Vec<(u32, String)>,
    /// Services under the prefix.
    pub services: Vec<String>,
    /// Nodes of the run's processes.
    pub nodes: Vec<LeftNode>,
}

impl Leftovers {
    /// Whether nothing was left.
    pub fn clean(&self) -> bool {
        self.processes.is_empty() && self.services.is_empty() && self.nodes.is_empty()
    }
}

fn processes_of(prefix: &str) -> Vec<(u32, String)> {
    super::memory::pids()
        .filter_map(|pid| {
            let args = cmdline(pid);
            args.windows(2)
                .any(|w| w[0] == "--prefix" && w[1] == prefix)
                .then(|| (pid, args.join(" ")))
        })
        .collect()
}

fn nodes_of(pids: &BTreeSet<u32>) -> Vec<LeftNode> {
    let mut out = Vec::new();
    let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
        let id = state.node_id();
        let pid = id
            .pid::<ipc::Service>()
            .map(|p| p.value() as u32)
            .unwrap_or(0);
        if pids.contains(&pid) {
            let name =
                |v: &dyn NodeView| v.details().as_ref().map(|d| d.name().as_str().to_string());
            let (state, name) = match &state {
                NodeState::Alive(v) => ("alive", name(v)),
                NodeState::Dead(v) => ("dead", name(v)),
                NodeState::Inaccessible(_) => ("inaccessible", None),
                NodeState::Undefined(_) => ("undefined", None),
            };
            out.push(LeftNode {
                pid,
                name: name.unwrap_or_default(),
                state,
            });
        }
        CallbackProgression::Continue
    });
    out
}

/// Looks for what the run under `prefix`, whose processes were `pids`, left behind; looks again
/// for up to `settle` while something is found (a process in its last milliseconds).
pub fn find(prefix: &str, pids: &BTreeSet<u32>, settle: Duration) -> Leftovers {
    let start = Instant::now();
    loop {
        let found = Leftovers {
            processes: processes_of(prefix),
            services: lop_ipc::services::list_services(prefix),
            nodes: nodes_of(pids),
        };
        if found.clean() || start.elapsed() >= settle {
            return found;
        }
        std::thread::sleep(Duration::from_millis(200));
    }
}

// ---------------------------------------------------------------------------------------------
// The checks on this evidence.

/// Nothing of the run left after it.
pub(super) fn check_clean(e: &Evidence<'_>) -> Check {
    let leftovers = e.leftovers;
    check(
        "nothing left behind (processes, iceoryx2 services and nodes of the run)",
        leftovers.clean(),
        format!(
            "{} processes, {} services, {} nodes left{}",
            leftovers.processes.len(),
            leftovers.services.len(),
            leftovers.nodes.len(),
            if leftovers.clean() {
                String::new()
            } else {
                format!(
                    ": {:?} {:?} {:?}",
                    leftovers.processes, leftovers.services, leftovers.nodes
                )
            }
        ),
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_live_node_and_a_process_of_the_prefix_are_found_and_then_gone() {
        // The check can fail: a node of this process is found while it exists.
        let me: BTreeSet<u32> = [std::process::id()].into();
        let node = lop_ipc::services::node("lop-bench-leftover-test").unwrap();
        let found = nodes_of(&me);
        assert!(
            found
                .iter()
                .any(|n| n.name == "lop-bench-leftover-test" && n.state == "alive"),
            "{found:?}"
        );
        drop(node);
        assert!(nodes_of(&me)
            .iter()
            .all(|n| n.name != "lop-bench-leftover-test"));

        // A process whose arguments name the prefix.
        let prefix = format!("lopbench-leftover-test-{}", std::process::id());
        // The shell waits on a builtin (`read` from a pipe), so it never forks: a forked child
        // carries the shell's arguments until it execs, and a loaded machine catches it there.
        let mut child = std::process::Command::new("sh")
            .args(["-c", "read _", "--prefix", &prefix])
            .stdin(std::process::Stdio::piped())
            .spawn()
            .unwrap();
        // Until it is seen (a busy machine has shown none for a moment right after the spawn).
        let start = Instant::now();
        while processes_of(&prefix).len() != 1 && start.elapsed() < Duration::from_secs(5) {
            std::thread::sleep(Duration::from_millis(10));
        }
        assert_eq!(
            processes_of(&prefix).len(),
            1,
            "the shell: {:?}, {:?}",
            child.try_wait(),
            cmdline(child.id())
        );
        let _ = child.kill();
        let _ = child.wait();
        assert!(find(&prefix, &me, Duration::from_secs(1)).clean());
    }
}
