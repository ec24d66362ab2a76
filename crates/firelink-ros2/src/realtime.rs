//! Real-time scheduling for the threads a `servo_jp` point passes through
//! on its way to the boards (`--rt`, the default; `--no-rt` leaves them
//! alone).
//!
//! A point goes from the DDS socket through RustDDS's event loop thread
//! (which reads the socket and makes the subscription ready), the node's
//! thread (which takes it, queues it for the robot loop and wakes that
//! loop) and the robot loop's thread (whose next cycle writes it to the
//! boards). On a machine shared with other work, each of the three
//! wake-ups may wait for a CPU behind ordinary processes; that wait, not
//! the work, is the latency's tail. So each of the three gets `SCHED_FIFO`
//! (the robot loop highest: its cycle is short and its deadline the hard
//! one; then the socket reader, without which the node has nothing to
//! take; then the node), a 1 ns timer slack (so the robot loop's sleep
//! until its next cycle ends on time; the kernel gives real-time threads
//! no slack anyway), and the process's memory is locked (`mlockall`), so
//! no page fault stalls a cycle. None of the three spins: each sleeps in
//! `poll` or `park_timeout` until it has work, so real-time throttling
//! (`sched_rt_runtime_us`) never applies to them.
//!
//! The threads are found by name in `/proc/self/task` (the robot loop's
//! [`ROBOT_THREAD_NAME`], RustDDS's `RustDDS Participant N event loop`,
//! which the OS shortens to 15 bytes) and by id for the calling thread.
//! What cannot be set (no `CAP_SYS_NICE`, not Linux, a thread not found)
//! is reported in [`RealtimeReport::errors`] and the node runs on at normal
//! priority: never fatal.
//!
//! The system calls are behind [`Scheduler`], so the choice of threads and
//! priorities and the fallback are tested without changing any thread's
//! scheduling. The real ones, [`OsScheduler`], are
//! `firelink_testbed::realtime`'s (the tree's one home for them); the
//! crate has no unsafe code.

use std::io;

use firelink_testbed::dvrk::service::ROBOT_THREAD_NAME;
use firelink_testbed::realtime as os;

/// A thread on a servo point's path.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PathThread {
    /// The robot service's loop: runs the cycle whose write block carries
    /// the point.
    RobotLoop,
    /// RustDDS's event loop: reads the DDS sockets and makes the
    /// subscriptions ready.
    DdsEventLoop,
    /// The node's thread: takes the point, queues it and wakes the robot
    /// loop.
    Node,
}

/// How the OS shows RustDDS's event loop thread's name (`RustDDS
/// Participant N event loop`, cut to 15 bytes).
const DDS_EVENT_LOOP_PREFIX: &str = "RustDDS Partici";

impl PathThread {
    /// Its `SCHED_FIFO` priority (1-99): the robot loop first, then the
    /// socket reader, then the node.
    pub fn priority(self) -> i32 {
        match self {
            PathThread::RobotLoop => 80,
            PathThread::DdsEventLoop => 75,
            PathThread::Node => 70,
        }
    }

    /// Which thread of the path a thread named `name` is, by name alone
    /// (the node's thread is known by its id instead).
    pub fn named(name: &str) -> Option<PathThread> {
        let name = name.trim_end();
        if name == ROBOT_THREAD_NAME {
            Some(PathThread::RobotLoop)
        } else if name.starts_with(DDS_EVENT_LOOP_PREFIX) {
            Some(PathThread::DdsEventLoop)
        } else {
            None
        }
    }

    fn describe(self) -> &'static str {
        match self {
            PathThread::RobotLoop => "the robot loop's thread",
            PathThread::DdsEventLoop => "RustDDS's event loop thread",
            PathThread::Node => "the node's thread",
        }
    }
}

/// A thread of this process: its id and name.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Task {
    /// The thread's id (`gettid`).
    pub tid: i32,
    /// Its name, as `/proc/self/task/<tid>/comm` gives it.
    pub name: String,
}

/// Which threads get which settings: the path's threads found in `tasks`
/// (the calling thread, `own_tid`, is the node's), and the ones expected
/// but not found. `with_dds`: the DDS event loop is expected (not for a
/// run without DDS).
pub fn plan(
    tasks: &[Task],
    own_tid: i32,
    with_dds: bool,
) -> (Vec<(i32, PathThread)>, Vec<PathThread>) {
    let mut found = vec![(own_tid, PathThread::Node)];
    for task in tasks {
        if task.tid == own_tid {
            continue;
        }
        if let Some(role) = PathThread::named(&task.name)
            && (with_dds || role != PathThread::DdsEventLoop)
        {
            found.push((task.tid, role));
        }
    }
    let mut expected = vec![PathThread::RobotLoop, PathThread::Node];
    if with_dds {
        expected.insert(1, PathThread::DdsEventLoop);
    }
    let missing = expected
        .into_iter()
        .filter(|role| !found.iter().any(|(_, r)| r == role))
        .collect();
    found.sort_by_key(|&(tid, role)| (std::cmp::Reverse(role.priority()), tid));
    (found, missing)
}

/// The system calls behind [`apply`].
pub trait Scheduler {
    /// This process's threads.
    fn tasks(&self) -> io::Result<Vec<Task>>;
    /// The calling thread's id.
    fn own_tid(&self) -> i32;
    /// Lock the process's memory, now and to come.
    fn lock_memory(&mut self) -> io::Result<()>;
    /// Set thread `tid`'s timer slack to 1 ns.
    fn set_timer_slack_1ns(&mut self, tid: i32) -> io::Result<()>;
    /// Thread `tid`'s timer slack, ns, as the kernel has it now.
    fn timer_slack_ns(&self, tid: i32) -> Option<u64>;
    /// Give thread `tid` `SCHED_FIFO` at `priority`.
    fn set_fifo(&mut self, tid: i32, priority: i32) -> io::Result<()>;
}

/// What one thread got.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct ThreadSetting {
    /// Which thread of the path.
    pub thread: PathThread,
    /// Its id.
    pub tid: i32,
    /// `SCHED_FIFO` at this priority, if it took.
    pub sched_fifo: Option<i32>,
    /// Its timer slack afterwards, ns (`None`: not readable).
    pub timer_slack_ns: Option<u64>,
}

/// What the real-time settings came to, for the node's JSON report.
#[derive(Debug, Clone, Default, PartialEq, Eq, serde::Serialize)]
pub struct RealtimeReport {
    /// The settings were asked for (`--rt`, the default; false with
    /// `--no-rt`).
    pub requested: bool,
    /// Every setting asked for took effect on every thread of the path.
    pub applied: bool,
    /// The process's memory is locked.
    pub memory_locked: bool,
    /// Each thread of the path found, and what it got.
    pub threads: Vec<ThreadSetting>,
    /// Why a setting did not take (the node then runs on without it).
    pub errors: Vec<String>,
}

/// Apply the settings to the path's threads through `scheduler`; never
/// fails: what did not take is in the report's errors.
pub fn apply(scheduler: &mut impl Scheduler, with_dds: bool) -> RealtimeReport {
    let mut report = RealtimeReport {
        requested: true,
        ..RealtimeReport::default()
    };
    match scheduler.lock_memory() {
        Ok(()) => report.memory_locked = true,
        Err(e) => report.errors.push(format!("mlockall: {e}")),
    }
    let tasks = scheduler.tasks().unwrap_or_else(|e| {
        report
            .errors
            .push(format!("this process's threads could not be listed: {e}"));
        Vec::new()
    });
    let (threads, missing) = plan(&tasks, scheduler.own_tid(), with_dds);
    for role in missing {
        report
            .errors
            .push(format!("{} was not found: left as it is", role.describe()));
    }
    for (tid, thread) in threads {
        // The slack first: the kernel ignores a slack asked for a
        // real-time thread (it has none).
        if let Err(e) = scheduler.set_timer_slack_1ns(tid) {
            report
                .errors
                .push(format!("timer slack of {}: {e}", thread.describe()));
        }
        let sched_fifo = match scheduler.set_fifo(tid, thread.priority()) {
            Ok(()) => Some(thread.priority()),
            Err(e) => {
                report.errors.push(format!(
                    "SCHED_FIFO {} for {}: {e}",
                    thread.priority(),
                    thread.describe()
                ));
                None
            }
        };
        report.threads.push(ThreadSetting {
            thread,
            tid,
            sched_fifo,
            timer_slack_ns: scheduler.timer_slack_ns(tid),
        });
    }
    report.applied = report.errors.is_empty();
    report
}

/// The real system calls, made by `firelink_testbed::realtime` (Linux;
/// elsewhere each one is refused as unsupported).
#[derive(Debug, Default)]
pub struct OsScheduler;

impl Scheduler for OsScheduler {
    fn tasks(&self) -> io::Result<Vec<Task>> {
        let mut tasks = Vec::new();
        for entry in std::fs::read_dir("/proc/self/task")? {
            let entry = entry?;
            let Some(tid) = entry.file_name().to_str().and_then(|t| t.parse().ok()) else {
                continue;
            };
            // A thread that ended meanwhile has no name to read.
            if let Ok(name) = std::fs::read_to_string(entry.path().join("comm")) {
                tasks.push(Task { tid, name });
            }
        }
        Ok(tasks)
    }

    fn own_tid(&self) -> i32 {
        os::current_tid()
    }

    fn lock_memory(&mut self) -> io::Result<()> {
        os::lock_memory()
    }

    fn set_timer_slack_1ns(&mut self, tid: i32) -> io::Result<()> {
        os::set_timer_slack(tid, 1)
    }

    fn timer_slack_ns(&self, tid: i32) -> Option<u64> {
        os::timer_slack_ns(tid)
    }

    fn set_fifo(&mut self, tid: i32, priority: i32) -> io::Result<()> {
        os::set_fifo(tid, priority)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn task(tid: i32, name: &str) -> Task {
        Task {
            tid,
            name: format!("{name}\n"),
        }
    }

    /// A process as `firelink ros2` has it: the main thread (the node's),
    /// the robot loop, RustDDS's event loop and discovery threads, and a
    /// thread of another name.
    fn node_process() -> Vec<Task> {
        vec![
            task(100, "firelink-ros2"),
            task(101, "firelink-robot"),
            task(102, "RustDDS Partici"),
            task(103, "RustDDS discove"),
            task(104, "firelink-ros2"),
        ]
    }

    #[test]
    fn the_path_threads_are_found_by_name_and_the_caller_by_id() {
        assert_eq!(
            PathThread::named("firelink-robot\n"),
            Some(PathThread::RobotLoop)
        );
        assert_eq!(
            PathThread::named("RustDDS Participant 0 event loop"),
            Some(PathThread::DdsEventLoop)
        );
        assert_eq!(PathThread::named("RustDDS discove"), None);
        let (threads, missing) = plan(&node_process(), 100, true);
        assert_eq!(
            threads,
            [
                (101, PathThread::RobotLoop),
                (102, PathThread::DdsEventLoop),
                (100, PathThread::Node)
            ]
        );
        assert!(missing.is_empty());
        // Without DDS the event loop is neither expected nor touched.
        let (threads, missing) = plan(&node_process(), 100, false);
        assert_eq!(
            threads,
            [(101, PathThread::RobotLoop), (100, PathThread::Node)]
        );
        assert!(missing.is_empty());
        // Missing threads are named.
        let (threads, missing) = plan(&[task(7, "firelink-ros2")], 7, true);
        assert_eq!(threads, [(7, PathThread::Node)]);
        assert_eq!(missing, [PathThread::RobotLoop, PathThread::DdsEventLoop]);
    }

    #[test]
    fn the_robot_loop_ranks_first_then_the_socket_reader_then_the_node() {
        let p = |t: PathThread| t.priority();
        assert!(p(PathThread::RobotLoop) > p(PathThread::DdsEventLoop));
        assert!(p(PathThread::DdsEventLoop) > p(PathThread::Node));
        assert!(p(PathThread::Node) >= 1 && p(PathThread::RobotLoop) <= 99);
    }

    /// The system calls on made-up threads: what each thread was asked
    /// for, and a refusal of any of them.
    struct FakeScheduler {
        tasks: Vec<Task>,
        refuse: Option<io::ErrorKind>,
        fifo: Vec<(i32, i32)>,
        slack: Vec<(i32, u64)>,
    }

    impl FakeScheduler {
        fn new(refuse: Option<io::ErrorKind>) -> FakeScheduler {
            FakeScheduler {
                tasks: node_process(),
                refuse,
                fifo: Vec::new(),
                slack: Vec::new(),
            }
        }

        fn outcome(&self) -> io::Result<()> {
            self.refuse
                .map_or(Ok(()), |kind| Err(io::Error::from(kind)))
        }
    }

    impl Scheduler for FakeScheduler {
        fn tasks(&self) -> io::Result<Vec<Task>> {
            Ok(self.tasks.clone())
        }
        fn own_tid(&self) -> i32 {
            100
        }
        fn lock_memory(&mut self) -> io::Result<()> {
            self.outcome()
        }
        fn set_timer_slack_1ns(&mut self, tid: i32) -> io::Result<()> {
            self.outcome()?;
            self.slack.push((tid, 1));
            Ok(())
        }
        fn timer_slack_ns(&self, tid: i32) -> Option<u64> {
            Some(
                self.slack
                    .iter()
                    .find(|(t, _)| *t == tid)
                    .map_or(50_000, |(_, ns)| *ns),
            )
        }
        fn set_fifo(&mut self, tid: i32, priority: i32) -> io::Result<()> {
            self.outcome()?;
            self.fifo.push((tid, priority));
            Ok(())
        }
    }

    #[test]
    fn every_path_thread_gets_its_priority_and_a_1ns_slack() {
        let mut s = FakeScheduler::new(None);
        let report = apply(&mut s, true);
        assert!(report.requested && report.applied && report.memory_locked);
        assert!(report.errors.is_empty(), "{:?}", report.errors);
        assert_eq!(s.fifo, [(101, 80), (102, 75), (100, 70)]);
        assert_eq!(s.slack, [(101, 1), (102, 1), (100, 1)]);
        assert!(
            report
                .threads
                .iter()
                .all(|t| t.sched_fifo == Some(t.thread.priority()) && t.timer_slack_ns == Some(1))
        );
        // The discovery thread was left alone.
        assert!(!s.fifo.iter().any(|&(tid, _)| tid == 103));
    }

    /// Without the privilege every setting is refused: the report says so,
    /// thread by thread, and nothing fails.
    #[test]
    fn refusals_are_reported_and_the_node_runs_on_without() {
        let mut s = FakeScheduler::new(Some(io::ErrorKind::PermissionDenied));
        let report = apply(&mut s, true);
        assert!(report.requested);
        assert!(!report.applied && !report.memory_locked);
        assert_eq!(report.threads.len(), 3);
        assert!(report.threads.iter().all(|t| t.sched_fifo.is_none()));
        assert!(report.errors.iter().any(|e| e.starts_with("mlockall")));
        let fifo_refusals: Vec<&String> = report
            .errors
            .iter()
            .filter(|e| e.starts_with("SCHED_FIFO"))
            .collect();
        assert_eq!(fifo_refusals.len(), 3, "{:?}", report.errors);
        assert!(
            fifo_refusals[0].contains("robot loop"),
            "{:?}",
            report.errors
        );
    }

    #[test]
    fn a_thread_not_found_is_reported() {
        let mut s = FakeScheduler::new(None);
        s.tasks.retain(|t| !t.name.starts_with("RustDDS"));
        let report = apply(&mut s, true);
        assert!(!report.applied);
        assert_eq!(
            report.errors,
            ["RustDDS's event loop thread was not found: left as it is"]
        );
        assert_eq!(report.threads.len(), 2);
    }
}
