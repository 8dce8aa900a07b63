//! `lopd doctor`: checks that this machine can run a lop rig, and prints a concrete fix for
//! every problem.
//!
//! Each check reports OK, WARN (runs, but worse than it should) or FAIL (fix before use) with
//! what it measured. Checks: the daemon config; real-time privileges (`SCHED_FIFO`, memory
//! locking); the kernel's preemption model; CPU isolation and affinity of the haptic core; the
//! vendor library and the device itself (OpenHaptics: access to `/dev/fw*`, `/dev/ttyACM*`;
//! Force Dimension: every device the DHD SDK sees, and which one `--device` opens); free
//! shared memory in `/dev/shm`; stale iceoryx2 resources left by crashed processes. Exit code 1
//! when any check fails. Nothing is changed on the machine except, with `--clean`, removing the
//! resources of dead iceoryx2 nodes.

use std::ffi::CString;
use std::path::{Path, PathBuf};

use iceoryx2::prelude::*;
use lop_config::{load_daemon_config, DaemonConfig};
use lop_drivers::forcedimension::{self, ForceDimensionDevice};
use lop_drivers::openhaptics::{OpenHapticsDevice, LIBRARY_ENV};
use lop_drivers::{DeviceOpenError, DeviceSpec, HapticDevice};
use serde::Serialize;

use crate::rt;

/// Where the systemd unit reads the daemon config.
pub const STANDARD_CONFIG: &str = "/etc/lop/lopd.toml";

/// Free `/dev/shm` below this fails: lop's services need a few MiB per scene, and iceoryx2
/// reserves more.
const SHM_FAIL_BYTES: u64 = 64 << 20;
/// … below this warns.
const SHM_WARN_BYTES: u64 = 256 << 20;

/// How a check came out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "UPPERCASE")]
pub enum Status {
    /// Fine.
    Ok,
    /// Works, but not as it should on a rig.
    Warn,
    /// Must be fixed.
    Fail,
}

/// One check's result.
#[derive(Clone, Debug, Serialize)]
pub struct Finding {
    /// Short name (`rt-priority`).
    pub check: &'static str,
    /// Outcome.
    pub status: Status,
    /// What was measured.
    pub value: String,
    /// What to do about it (for WARN and FAIL).
    pub fix: Option<String>,
}

fn ok(check: &'static str, value: impl Into<String>) -> Finding {
    Finding {
        check,
        status: Status::Ok,
        value: value.into(),
        fix: None,
    }
}

fn problem(
    check: &'static str,
    status: Status,
    value: impl Into<String>,
    fix: impl Into<String>,
) -> Finding {
    Finding {
        check,
        status,
        value: value.into(),
        fix: Some(fix.into()),
    }
}

/// What to check.
pub struct DoctorOptions {
    /// `--config`; without it, [`STANDARD_CONFIG`] if it exists.
    pub config: Option<PathBuf>,
    /// The devices the rig uses, one per tool in the scene's order.
    pub devices: Vec<DeviceSpec>,
    /// The names of the tools they drive (the scene's, with `--scene`; else `tool1`…); a
    /// tool past the devices gets the mock.
    pub tools: Vec<String>,
    /// Service prefix.
    pub prefix: String,
    /// Remove the resources of dead iceoryx2 nodes.
    pub clean: bool,
}

/// Runs every check.
pub fn run(opts: &DoctorOptions) -> Vec<Finding> {
    let mut out = Vec::new();
    let config = check_config(opts.config.as_deref(), &mut out);
    out.push(check_rt_priority(&config));
    out.push(check_memory_lock(&config));
    out.push(check_kernel());
    let core = config.haptic.core.or_else(rt::last_core);
    out.push(check_affinity(core));
    out.push(check_isolation(core));
    for (k, spec) in opts.devices.iter().enumerate() {
        let first = out.len();
        check_device(spec, &config, &mut out);
        if opts.devices.len() > 1 || opts.tools.len() > 1 {
            let tool = opts.tools.get(k).map_or("?", String::as_str);
            for f in &mut out[first..] {
                f.value = format!("tool {tool:?}: {}", f.value);
            }
        }
    }
    if opts.tools.len() > 1 || opts.devices.len() > 1 {
        let map: Vec<String> = opts
            .tools
            .iter()
            .enumerate()
            .map(|(k, t)| match opts.devices.get(k) {
                Some(d) => format!("{t:?} ← {d}"),
                None => format!("{t:?} ← mock (no --device for it: it plays its script)"),
            })
            .collect();
        out.push(ok("tools", format!("devices by tool: {}", map.join(", "))));
    }
    out.push(check_shm());
    out.push(check_ipc(&opts.prefix, opts.clean));
    out
}

fn check_config(explicit: Option<&Path>, out: &mut Vec<Finding>) -> DaemonConfig {
    let path = match explicit {
        Some(p) => Some(p.to_path_buf()),
        None => Some(PathBuf::from(STANDARD_CONFIG)).filter(|p| p.exists()),
    };
    match path {
        None => {
            out.push(problem(
                "config",
                Status::Warn,
                format!("no --config and no {STANDARD_CONFIG}: built-in defaults"),
                format!(
                    "install the rig's config: sudo install -D -m 644 deploy/lopd.toml \
                     {STANDARD_CONFIG}"
                ),
            ));
            DaemonConfig::default()
        }
        Some(p) => match load_daemon_config(&p) {
            Ok(c) => {
                out.push(ok("config", format!("{} is valid", p.display())));
                c
            }
            Err(e) => {
                out.push(problem(
                    "config",
                    Status::Fail,
                    format!("{e}"),
                    format!("correct the key named above in {}", p.display()),
                ));
                DaemonConfig::default()
            }
        },
    }
}

fn rlimit(resource: libc::__rlimit_resource_t) -> Option<u64> {
    let mut r = libc::rlimit {
        rlim_cur: 0,
        rlim_max: 0,
    };
    // SAFETY: valid out-pointer.
    (unsafe { libc::getrlimit(resource, &mut r) } == 0).then_some(r.rlim_cur)
}

fn show_limit(v: Option<u64>) -> String {
    match v {
        Some(libc::RLIM_INFINITY) => "unlimited".into(),
        Some(v) => v.to_string(),
        None => "unknown".into(),
    }
}

const LIMITS_FIX: &str = "as a service: the unit's LimitRTPRIO=99 and LimitMEMLOCK=infinity \
     (deploy/lopd.service); interactively: sudo cp deploy/99-lop.conf /etc/security/limits.d/, \
     add yourself to the group (sudo usermod -aG lop $USER) and log in again; check with \
     `ulimit -r -l`";

fn check_rt_priority(config: &DaemonConfig) -> Finding {
    let priority = config.haptic.rt_priority;
    let limit = rlimit(libc::RLIMIT_RTPRIO);
    // Try on a throw-away thread so this process keeps its normal policy.
    let tried = std::thread::spawn(move || rt::set_fifo(priority))
        .join()
        .unwrap_or_else(|_| Err("the probe thread panicked".into()));
    match tried {
        Ok(()) => ok(
            "rt-priority",
            format!(
                "SCHED_FIFO priority {priority} granted (RLIMIT_RTPRIO {})",
                show_limit(limit)
            ),
        ),
        Err(_) => problem(
            "rt-priority",
            Status::Fail,
            format!(
                "SCHED_FIFO priority {priority} refused (RLIMIT_RTPRIO {}, no CAP_SYS_NICE): \
                 the haptic loop would run with normal priority and jitter",
                show_limit(limit)
            ),
            LIMITS_FIX,
        ),
    }
}

fn check_memory_lock(config: &DaemonConfig) -> Finding {
    let limit = rlimit(libc::RLIMIT_MEMLOCK);
    if !config.haptic.lock_memory {
        return problem(
            "memory-lock",
            Status::Warn,
            format!(
                "haptic.lock_memory = false (RLIMIT_MEMLOCK {})",
                show_limit(limit)
            ),
            "set lock_memory = true under [haptic]: a page fault on the haptic thread is a missed tick",
        );
    }
    // SAFETY: plain syscalls; the lock is released right away.
    let locked = unsafe { libc::mlockall(libc::MCL_CURRENT) } == 0;
    if locked {
        // SAFETY: as above.
        unsafe { libc::munlockall() };
        ok(
            "memory-lock",
            format!("mlockall allowed (RLIMIT_MEMLOCK {})", show_limit(limit)),
        )
    } else {
        problem(
            "memory-lock",
            Status::Fail,
            format!(
                "mlockall refused (RLIMIT_MEMLOCK {} bytes)",
                show_limit(limit)
            ),
            LIMITS_FIX,
        )
    }
}

fn check_kernel() -> Finding {
    let rt_flag = std::fs::read_to_string("/sys/kernel/realtime").unwrap_or_default();
    let version = std::fs::read_to_string("/proc/sys/kernel/version").unwrap_or_default();
    let version = version.trim();
    let preempt = std::fs::read_to_string("/sys/kernel/debug/sched/preempt").unwrap_or_default();
    if rt_flag.trim() == "1" || version.contains("PREEMPT_RT") {
        ok("kernel", format!("PREEMPT_RT ({version})"))
    } else {
        problem(
            "kernel",
            Status::Warn,
            format!(
                "not a PREEMPT_RT kernel ({version}{})",
                if preempt.is_empty() {
                    String::new()
                } else {
                    format!("; preempt mode {}", preempt.trim())
                }
            ),
            "for the lowest jitter install a real-time kernel (Debian: linux-image-rt-amd64; \
             Ubuntu: the lowlatency kernel or Ubuntu Pro's realtime kernel) and reboot into it; \
             a PREEMPT_DYNAMIC kernel can boot with preempt=full",
        )
    }
}

/// CPUs this process may run on.
fn allowed_cpus() -> Vec<usize> {
    // SAFETY: zeroed cpu_set_t is a valid empty set; sched_getaffinity fills it.
    unsafe {
        let mut set: libc::cpu_set_t = std::mem::zeroed();
        if libc::sched_getaffinity(0, std::mem::size_of::<libc::cpu_set_t>(), &mut set) != 0 {
            return Vec::new();
        }
        (0..libc::CPU_SETSIZE as usize)
            .filter(|&c| libc::CPU_ISSET(c, &set))
            .collect()
    }
}

/// Parses a kernel CPU list (`0-2,5`).
pub fn parse_cpu_list(text: &str) -> Vec<usize> {
    let mut cpus = Vec::new();
    for part in text.trim().split(',').filter(|p| !p.is_empty()) {
        match part.split_once('-') {
            Some((a, b)) => {
                if let (Ok(a), Ok(b)) = (a.trim().parse::<usize>(), b.trim().parse::<usize>()) {
                    cpus.extend(a..=b);
                }
            }
            None => {
                if let Ok(c) = part.trim().parse() {
                    cpus.push(c);
                }
            }
        }
    }
    cpus
}

fn check_affinity(core: Option<usize>) -> Finding {
    let allowed = allowed_cpus();
    let shown = format!("{allowed:?}");
    match core {
        None => problem(
            "cpu-affinity",
            Status::Warn,
            "could not list the CPUs",
            "set [haptic] core in the config",
        ),
        Some(c) if allowed.contains(&c) => ok(
            "cpu-affinity",
            format!("haptic core {c}; this process may run on CPUs {shown}"),
        ),
        Some(c) => problem(
            "cpu-affinity",
            Status::Fail,
            format!("haptic core {c} is not among the CPUs this process may use {shown}"),
            "set [haptic] core to one of those CPUs, or widen the unit's CPUAffinity= / the \
             container's cpuset",
        ),
    }
}

fn check_isolation(core: Option<usize>) -> Finding {
    let isolated = parse_cpu_list(
        &std::fs::read_to_string("/sys/devices/system/cpu/isolated").unwrap_or_default(),
    );
    let nohz = parse_cpu_list(
        &std::fs::read_to_string("/sys/devices/system/cpu/nohz_full").unwrap_or_default(),
    );
    let Some(core) = core else {
        return problem(
            "cpu-isolation",
            Status::Warn,
            "no haptic core",
            "set [haptic] core",
        );
    };
    let cpus = std::thread::available_parallelism().map_or(1, |n| n.get());
    if isolated.contains(&core) {
        ok(
            "cpu-isolation",
            format!("haptic core {core} is isolated (isolcpus {isolated:?}, nohz_full {nohz:?})"),
        )
    } else {
        problem(
            "cpu-isolation",
            Status::Warn,
            format!(
                "haptic core {core} is shared with other work (isolated CPUs: {isolated:?}; \
                 {cpus} CPUs)"
            ),
            format!(
                "reserve the core: add `isolcpus={core} nohz_full={core} rcu_nocbs={core}` to \
                 GRUB_CMDLINE_LINUX_DEFAULT in /etc/default/grub, run sudo update-grub and \
                 reboot; keep [haptic] core = {core} and the unit's CPUAffinity covering it{}",
                if cpus < 4 {
                    " (with fewer than 4 CPUs, leave at least one for the deformation process)"
                } else {
                    ""
                }
            ),
        )
    }
}

/// Device nodes of haptic devices this user cannot open read-write.
fn device_nodes() -> (Vec<String>, Vec<String>) {
    let mut found = Vec::new();
    let mut denied = Vec::new();
    let Ok(dir) = std::fs::read_dir("/dev") else {
        return (found, denied);
    };
    let mut names: Vec<String> = dir
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with("fw") || n.starts_with("ttyACM"))
        .collect();
    names.sort();
    for n in names {
        let path = format!("/dev/{n}");
        let c = CString::new(path.clone()).expect("no NUL in /dev names");
        // SAFETY: valid C string.
        if unsafe { libc::access(c.as_ptr(), libc::R_OK | libc::W_OK) } != 0 {
            denied.push(path.clone());
        }
        found.push(path);
    }
    (found, denied)
}

fn check_device(spec: &DeviceSpec, config: &DaemonConfig, out: &mut Vec<Finding>) {
    match spec {
        DeviceSpec::OpenHaptics { name } => check_openhaptics(spec, name, config, out),
        DeviceSpec::ForceDimension { id } => check_force_dimension(*id, config, out),
        _ => out.push(ok(
            "device",
            format!("--device {spec}: no hardware or vendor library needed"),
        )),
    }
}

/// A vendor library that did not load (`e`): a FAIL with `fix`, and the device not probed
/// (`unprobed` says why).
fn library_missing(e: &DeviceOpenError, fix: String, unprobed: String, out: &mut Vec<Finding>) {
    let why = match e {
        DeviceOpenError::Unavailable { reason, .. } => reason.clone(),
        other => other.to_string(),
    };
    out.push(problem("device-library", Status::Fail, why, fix));
    out.push(problem(
        "device",
        Status::Fail,
        unprobed,
        "fix device-library first",
    ));
}

/// The DHD library, every Force Dimension device it sees (index, type, serial), and the one
/// `--device dhd[:ID]` opens, started for a moment (zero force) to show it answers.
fn check_force_dimension(id: Option<u8>, config: &DaemonConfig, out: &mut Vec<Finding>) {
    let configured = config.device.dhd_library.as_deref();
    let env = forcedimension::LIBRARY_ENV;
    let found = match ForceDimensionDevice::discover(configured) {
        Ok(found) => found,
        Err(e) => {
            return library_missing(
                &e,
                format!(
                    "install the Force Dimension SDK (libdhd.so; its `make install` puts it in \
                     /usr/local/lib), or point {env} / [device] dhd_library in the config at \
                     the library; for a rig without a device use --device mock"
                ),
                "not probed: no DHD library".to_owned(),
                out,
            )
        }
    };
    let library = found.library.display().to_string();
    out.push(ok(
        "device-library",
        format!("loaded {library} (SDK {})", found.sdk_version),
    ));
    let index = id.unwrap_or(0);
    let spec = DeviceSpec::ForceDimension { id };
    if found.devices.is_empty() {
        out.push(problem(
            "device",
            Status::Fail,
            format!(
                "{library} (chosen by {env}, else [device] dhd_library, else the usual \
                     places) sees no Force Dimension device"
            ),
            format!(
                "connect the device by USB and power it, let it finish its calibration, give \
                 this user access to it (udev rule for its USB IDs, docs/deploy.md); if another \
                 SDK is meant, point {env} at its libdhd.so"
            ),
        ));
        return;
    }
    let listing = found
        .devices
        .iter()
        .map(|d| {
            let what = match &d.system_type {
                Ok(t) => format!(
                    "{} (type {t}{})",
                    d.system_name.as_deref().or(d.model).unwrap_or("unnamed"),
                    if d.model.is_some() {
                        ""
                    } else {
                        ", not in lop's limits table"
                    }
                ),
                Err(e) => e.clone(),
            };
            let serial = d
                .serial
                .map(|s| format!(", serial {s}"))
                .unwrap_or_default();
            let chosen = if d.index == index {
                " <- --device opens this one"
            } else {
                ""
            };
            format!("[{}] {what}{serial}{chosen}", d.index)
        })
        .collect::<Vec<_>>()
        .join("; ");
    let count = found.devices.len();
    if usize::from(index) >= count {
        out.push(problem(
            "device",
            Status::Fail,
            format!("--device {spec} opens index {index}, but {library} sees {count}: {listing}"),
            format!(
                "use one of the indices listed: --device dhd:0 to dhd:{}",
                count - 1
            ),
        ));
        return;
    }
    let mut device = match ForceDimensionDevice::open(id, configured) {
        Ok(d) => d,
        Err(e) => {
            out.push(problem(
                "device",
                Status::Fail,
                e.to_string(),
                "see device-library",
            ));
            return;
        }
    };
    match answer(&mut device, |d| Some(d.model().name.to_owned())) {
        Ok(answer) => out.push(ok(
            "device",
            format!("{count} Force Dimension device(s): {listing}; {spec} answers: {answer}"),
        )),
        Err(e) => out.push(problem(
            "device",
            Status::Fail,
            format!("{count} Force Dimension device(s): {listing}; {e}"),
            "check that no other program holds the device and that it finished its \
             calibration; `--device dhd:ID` picks another index",
        )),
    }
}

/// Starts `device`, reads it once and stops it: its model (`model`, asked once it has started;
/// if known), limits and where its tip is, as the doctor reports them.
fn answer<D: HapticDevice>(
    device: &mut D,
    model: impl Fn(&D) -> Option<String>,
) -> Result<String, DeviceOpenError> {
    device.start()?;
    let model = model(device);
    let limits = device.limits();
    let position = device.read(0.0);
    device.stop();
    Ok(format!(
        "{}peak {} N, continuous {} N, stiffness {} N/mm, workspace {:?}..{:?} mm{}",
        model.map(|m| format!("{m}, ")).unwrap_or_default(),
        limits.max_force_n,
        limits.max_continuous_force_n,
        limits.max_stiffness_n_per_mm,
        limits.workspace_min_mm,
        limits.workspace_max_mm,
        match position {
            Ok(s) => format!(", tip at {:?} mm", s.position_mm),
            Err(e) => format!(", read failed: {e}"),
        }
    ))
}

fn check_openhaptics(
    spec: &DeviceSpec,
    name: &Option<String>,
    config: &DaemonConfig,
    out: &mut Vec<Finding>,
) {
    let (nodes, denied) = device_nodes();
    let nodes_text = if nodes.is_empty() {
        "no /dev/fw* or /dev/ttyACM* device nodes".to_string()
    } else {
        format!("device nodes {nodes:?}")
    };
    if !denied.is_empty() {
        out.push(problem(
            "device-permissions",
            Status::Warn,
            format!("no read-write access to {denied:?}"),
            "install the udev rule: sudo cp deploy/99-lop-haptics.rules /etc/udev/rules.d/ && \
             sudo udevadm control --reload && sudo udevadm trigger, and add the service user to \
             plugdev (sudo usermod -aG plugdev lop); see docs/deploy.md",
        ));
    }
    let mut device =
        match OpenHapticsDevice::open(name.as_deref(), config.device.hd_library.as_deref()) {
            Ok(d) => {
                out.push(ok(
                    "device-library",
                    format!("loaded {}", d.library_path().display()),
                ));
                d
            }
            Err(e) => {
                return library_missing(
                    &e,
                    format!(
                        "install OpenHaptics (libHD.so) and the device driver as in \
                         docs/deploy.md, or point {LIBRARY_ENV} / [device] hd_library in the \
                         config at the library; for a rig without a device use --device mock"
                    ),
                    format!("not probed: no HD library ({nodes_text})"),
                    out,
                )
            }
        };
    match answer(&mut device, |d| d.model().map(str::to_owned)) {
        Ok(answer) => out.push(ok("device", format!("{spec} answers: {answer}"))),
        Err(e) => out.push(problem(
            "device",
            Status::Fail,
            format!("{e} ({nodes_text})"),
            "connect and power the device; check its name (`lopd run --device openhaptics:NAME` \
             with the name from the vendor's setup tool), the permissions above, and that no \
             other program holds it; FireWire Omni vs USB/Ethernet Touch set-up: docs/deploy.md",
        )),
    }
}

fn check_shm() -> Finding {
    let path = CString::new("/dev/shm").expect("no NUL");
    // SAFETY: zeroed statvfs is a valid out-buffer.
    let mut st: libc::statvfs = unsafe { std::mem::zeroed() };
    // SAFETY: valid path and out-pointer.
    if unsafe { libc::statvfs(path.as_ptr(), &mut st) } != 0 {
        return problem(
            "shared-memory",
            Status::Fail,
            format!("/dev/shm: {}", std::io::Error::last_os_error()),
            "mount a tmpfs on /dev/shm (fstab: `tmpfs /dev/shm tmpfs defaults,size=1G 0 0`)",
        );
    }
    let free = st.f_bavail as u64 * st.f_frsize as u64;
    let total = st.f_blocks as u64 * st.f_frsize as u64;
    let value = format!("/dev/shm {} MiB free of {} MiB", free >> 20, total >> 20);
    let fix = "enlarge it: sudo mount -o remount,size=1G /dev/shm (and in /etc/fstab: `tmpfs \
               /dev/shm tmpfs defaults,size=1G 0 0`); in Docker run with --shm-size=1g; remove \
               stale iceoryx2 files (see stale-ipc)";
    if free < SHM_FAIL_BYTES {
        problem("shared-memory", Status::Fail, value, fix)
    } else if free < SHM_WARN_BYTES {
        problem("shared-memory", Status::Warn, value, fix)
    } else {
        ok("shared-memory", value)
    }
}

/// Whether a `lopd` process other than this one is running.
fn lopd_running() -> bool {
    let me = std::process::id().to_string();
    let Ok(dir) = std::fs::read_dir("/proc") else {
        return false;
    };
    dir.flatten().any(|e| {
        let name = e.file_name().to_string_lossy().into_owned();
        name != me
            && name.chars().all(|c| c.is_ascii_digit())
            && std::fs::read(e.path().join("cmdline"))
                .ok()
                .and_then(|c| {
                    let first = c.split(|&b| b == 0).next()?.to_vec();
                    let second = c.split(|&b| b == 0).nth(1)?.to_vec();
                    Some(
                        String::from_utf8_lossy(&first).ends_with("lopd")
                            && matches!(&second[..], b"run" | b"haptic" | b"deform"),
                    )
                })
                .unwrap_or(false)
    })
}

fn check_ipc(prefix: &str, clean: bool) -> Finding {
    // iceoryx2 would warn on stderr that it runs without a config file (on purpose).
    set_log_level(LogLevel::Error);
    let mut dead = 0;
    let listed = Node::<ipc::Service>::list(Config::global_config(), |state| {
        if let NodeState::Dead(_) = state {
            dead += 1;
        }
        CallbackProgression::Continue
    });
    if let Err(e) = listed {
        return problem(
            "stale-ipc",
            Status::Warn,
            format!("could not list iceoryx2 nodes: {e:?}"),
            "check that /tmp and /dev/shm are writable",
        );
    }
    let mut cleaned = 0;
    if clean && dead > 0 {
        if let Ok(node) = lop_ipc::services::node("lopd-doctor") {
            cleaned = lop_ipc::services::cleanup_dead_nodes(&node);
        }
    }
    let services = lop_ipc::services::list_services(prefix);
    let running = lopd_running();
    let left = !services.is_empty() && !running;
    let value = format!(
        "{dead} dead iceoryx2 node(s){}; {} service(s) under {prefix:?}{}",
        if cleaned > 0 {
            format!(" ({cleaned} cleaned)")
        } else {
            String::new()
        },
        services.len(),
        if running { ", lopd running" } else { "" }
    );
    if (dead > cleaned as usize) || left {
        problem(
            "stale-ipc",
            Status::Warn,
            value,
            "resources of crashed processes: `lopd doctor --clean` removes dead nodes (lopd also \
             does at start); if services remain with no lopd running, remove /tmp/iceoryx2 and \
             /dev/shm/iox2_* or reboot",
        )
    } else {
        ok("stale-ipc", value)
    }
}

/// Prints the findings as a table (or JSON); returns whether any failed.
pub fn print(findings: &[Finding], json: bool) -> bool {
    let failed = findings.iter().any(|f| f.status == Status::Fail);
    if json {
        println!(
            "{}",
            serde_json::to_string_pretty(findings).expect("findings serialise")
        );
        return failed;
    }
    for f in findings {
        let tag = match f.status {
            Status::Ok => "OK  ",
            Status::Warn => "WARN",
            Status::Fail => "FAIL",
        };
        println!("{tag}  {:<18} {}", f.check, f.value);
        if let Some(fix) = &f.fix {
            println!("      {:<18} fix: {fix}", "");
        }
    }
    let count = |s| findings.iter().filter(|f| f.status == s).count();
    println!(
        "{} OK, {} WARN, {} FAIL",
        count(Status::Ok),
        count(Status::Warn),
        count(Status::Fail)
    );
    failed
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cpu_lists() {
        assert_eq!(parse_cpu_list("0-2,5\n"), [0, 1, 2, 5]);
        assert_eq!(parse_cpu_list(""), Vec::<usize>::new());
        assert_eq!(parse_cpu_list("3"), [3]);
    }
}
