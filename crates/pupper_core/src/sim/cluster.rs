//! Sweeps on a cluster: the cells to run cut into tasks, each task one
//! node's batch of cells, sent to a [`Cluster`] (Ray, through the bridge)
//! and handed to the hooks (the run writer) as each one comes back, so a
//! stop or a dead driver loses only the tasks still running. Which node ran
//! a cell never changes its numbers: a task runs the same runner on the
//! same inputs as a local sweep.

use std::time::Duration;

use serde::{Deserialize, Serialize, de::DeserializeOwned};

use crate::error::{Error, Result};
use crate::plan::config::SweepConfig;
use crate::plan::grid::Cell;
use crate::sim::runner::{CellResult, DEFAULT_CHUNK_CELLS, Hooks};

/// Tasks per slot the cells are cut into when `--chunk-cells` does not
/// say: enough that a lost task costs little, fast nodes take more and the
/// progress bar moves, few enough that per-task costs (a model compiled per
/// task, a few ms) stay small. On a 2-core loopback cluster 8 per slot was
/// no slower than 1 (benches/bench_ray.py).
pub const TASKS_PER_SLOT: usize = 8;

/// Tasks in flight per slot: one running and one queued on each, so a node
/// never waits on the driver, and a stop has little to cancel.
const IN_FLIGHT_PER_SLOT: usize = 2;

/// How long one wait on the cluster lasts before stop is checked again.
const POLL: Duration = Duration::from_millis(100);

/// Where the cluster is: `auto` (Ray's `RAY_ADDRESS`, or the cluster this
/// machine is a node of), `ray://HOST:PORT` (Ray's client) or `HOST:PORT`
/// (the head's address, from a node of the cluster).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct Address(String);

impl Address {
    pub fn parse(text: &str) -> Result<Address> {
        let text = text.trim();
        let bad = || {
            Error::Config(format!(
                "--ray '{text}' is not a Ray address: give auto (uses RAY_ADDRESS), ray://HOST:PORT (Ray's client port, 10001 by default) or HOST:PORT (the head's port, from a node of the cluster)"
            ))
        };
        if text == "auto" {
            return Ok(Address(text.into()));
        }
        let hostport = text.strip_prefix("ray://").unwrap_or(text);
        let (host, port) = hostport.rsplit_once(':').ok_or_else(bad)?;
        if host.is_empty() || host.contains('/') || port.parse::<u16>().is_err() {
            return Err(bad());
        }
        Ok(Address(text.into()))
    }

    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl std::fmt::Display for Address {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.0)
    }
}

/// What every task of a sweep shares, sent to the cluster once: the inputs,
/// and what the driver ran against, which a worker must match (else its
/// numbers could differ from the driver's).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Job {
    pub config: SweepConfig,
    pub model_sha256: String,
    pub pupper_version: String,
    pub mujoco_version: String,
    /// Steps per open-loop call (servo mode), as the local runner uses.
    pub chunk_steps: usize,
}

/// One task: cells of the grid, run as one batch on one node.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Task {
    pub cells: Vec<Cell>,
}

/// What a task sends back.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Outcome {
    Done(Vec<CellResult>),
    /// The worker refused or failed: `user` when the fix is the user's (a
    /// model file missing on that node, another pupper version there).
    Failed {
        host: String,
        user: bool,
        message: String,
    },
}

/// Bytes for the wire: MessagePack with field names, which keeps every
/// f64 bit for bit (NaN included, which JSON cannot carry).
pub fn encode<T: Serialize>(value: &T) -> Result<Vec<u8>> {
    rmp_serde::to_vec_named(value).map_err(|e| Error::Internal(format!("encoding a task: {e}")))
}

pub fn decode<T: DeserializeOwned>(bytes: &[u8]) -> Result<T> {
    rmp_serde::from_slice(bytes).map_err(|e| {
        Error::Internal(format!(
            "decoding a task ({e}): are the driver and the workers the same pupper version?"
        ))
    })
}

/// How much a cluster runs at once.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Capacity {
    /// Tasks that run at the same time.
    pub slots: usize,
    /// Threads (CPUs) each task has.
    pub threads: usize,
}

/// A cluster that runs tasks: submit them, collect the finished ones.
pub trait Cluster {
    fn capacity(&self) -> Capacity;
    /// Sends task `id` (an encoded [`Task`]).
    fn submit(&mut self, id: usize, task: Vec<u8>) -> Result<()>;
    /// Tasks that finished, waiting at most `timeout` for the first (each
    /// an encoded [`Outcome`]). A task the cluster gave up on (its retries
    /// spent) is an error.
    fn wait(&mut self, timeout: Duration) -> Result<Vec<(usize, Vec<u8>)>>;
    /// Drops every task still queued or running.
    fn cancel(&mut self);
}

/// Cuts `cells` into tasks: `chunk_cells` cells each when given, else
/// about [`TASKS_PER_SLOT`] per slot, never fewer simulations than a task
/// has threads nor more cells than [`DEFAULT_CHUNK_CELLS`]. Grid order is
/// kept, so a task's cells are neighbours (they mostly share a body).
pub fn tasks(
    cells: &[Cell],
    capacity: Capacity,
    replicates: usize,
    chunk_cells: Option<usize>,
) -> Vec<Vec<Cell>> {
    let size = match chunk_cells {
        Some(n) => n,
        None => {
            let fill = capacity.threads.div_ceil(replicates.max(1));
            let share = cells.len().div_ceil(TASKS_PER_SLOT * capacity.slots.max(1));
            share.max(fill).min(DEFAULT_CHUNK_CELLS)
        }
    }
    .max(1);
    cells.chunks(size).map(<[Cell]>::to_vec).collect()
}

/// Runs `cells` of `job` on `cluster`, passing each finished task's
/// results to `hooks` (progress by `steps(cell)` cell-steps, then
/// `chunk_done`) in the order they finish. On stop, cancels what is still
/// running and returns `Error::Interrupted`; what was handed over is kept.
pub fn run_cells(
    cluster: &mut dyn Cluster,
    job: &Job,
    cells: &[Cell],
    chunk_cells: Option<usize>,
    steps: &dyn Fn(&Cell) -> u64,
    hooks: &mut dyn Hooks,
) -> Result<()> {
    let capacity = cluster.capacity();
    let replicates = job.config.sims_per_cell();
    let all = tasks(cells, capacity, replicates, chunk_cells);
    let in_flight = (IN_FLIGHT_PER_SLOT * capacity.slots).max(1);
    let mut state = InFlight {
        running: vec![None; all.len()],
        sent: 0,
        left: all.len(),
        steps,
        replicates: replicates as u64,
    };
    let mut next = 0;
    let result = (|| -> Result<()> {
        while state.left > 0 {
            if hooks.should_stop() {
                // what finished meanwhile is kept
                state.take(cluster.wait(Duration::ZERO)?, hooks)?;
                return Err(Error::Interrupted("stopped".into()));
            }
            while next < all.len() && state.sent < in_flight {
                let task = Task {
                    cells: all[next].clone(),
                };
                cluster.submit(next, encode(&task)?)?;
                state.running[next] = Some(task.cells);
                next += 1;
                state.sent += 1;
            }
            state.take(cluster.wait(POLL)?, hooks)?;
        }
        Ok(())
    })();
    if result.is_err() {
        cluster.cancel();
    }
    result
}

/// The tasks of a run between submit and hand-over.
struct InFlight<'a> {
    /// Each task's cells while it runs.
    running: Vec<Option<Vec<Cell>>>,
    /// Tasks sent and not back yet.
    sent: usize,
    /// Tasks not handed over yet.
    left: usize,
    steps: &'a dyn Fn(&Cell) -> u64,
    replicates: u64,
}

impl InFlight<'_> {
    /// Hands finished tasks over; a failed one is reported after the
    /// finished ones beside it are written, so none of them is lost.
    fn take(&mut self, done: Vec<(usize, Vec<u8>)>, hooks: &mut dyn Hooks) -> Result<()> {
        let mut failed = None;
        for (id, bytes) in done {
            let cells = self
                .running
                .get_mut(id)
                .and_then(Option::take)
                .ok_or_else(|| {
                    Error::Internal(format!(
                        "the cluster returned task {id} twice, or one never sent"
                    ))
                })?;
            self.sent -= 1;
            let results = match decode::<Outcome>(&bytes)? {
                Outcome::Done(r) => r,
                Outcome::Failed {
                    host,
                    user,
                    message,
                } => {
                    let text = format!("on node {host}: {message}");
                    failed.get_or_insert(match user {
                        true => Error::Cluster(text),
                        false => Error::Internal(text),
                    });
                    continue;
                }
            };
            let same = results.len() == cells.len()
                && results
                    .iter()
                    .zip(&cells)
                    .all(|(r, c)| r.cell.index == c.index);
            if !same {
                return Err(Error::Internal(format!(
                    "task {id} came back with other cells than it was sent"
                )));
            }
            hooks.progress(cells.iter().map(self.steps).sum::<u64>() * self.replicates);
            hooks.chunk_done(&results)?;
            self.left -= 1;
        }
        failed.map_or(Ok(()), Err)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plan::grid::Grid;
    use crate::sim::metrics::{Metrics, Status};

    fn cells(n: usize) -> Vec<Cell> {
        let kp: Vec<String> = (0..n).map(|i| (i + 1).to_string()).collect();
        Grid::parse(&[format!("kp={}", kp.join(","))])
            .unwrap()
            .cells()
    }

    fn result(cell: &Cell) -> CellResult {
        let kp = cell.values[0].1;
        CellResult {
            cell: cell.clone(),
            metrics: Metrics {
                final_z: kp / 1000.0,
                last_1s_std_mm: f64::NAN,
                push_dip_mm: -0.0,
                settle_time_s: f64::INFINITY,
                max_tilt_deg: 0.1 + 0.2,
                peak_torque: f64::MIN_POSITIVE,
                saturation_frac: 1.0 / 3.0,
                tracking_rms: 1e-300,
                status: Status::Fell,
                event_time: f64::NAN,
            },
            replicates: Vec::new(),
            trace: vec![(0.002, 0.14)],
            frames: None,
            joints: Vec::new(),
            figures: Vec::new(),
            steps: 0,
        }
    }

    /// Runs tasks in the order `order` picks among those submitted, `per_wait`
    /// at a time; remembers what it was asked.
    struct Fake {
        capacity: Capacity,
        queued: Vec<(usize, Task)>,
        per_wait: usize,
        /// Task ids in the order they were submitted.
        submitted: Vec<usize>,
        most_in_flight: usize,
        cancelled: bool,
        /// (task id, its outcome) for a task that fails.
        fail: Option<(usize, Outcome)>,
        newest_first: bool,
    }

    impl Fake {
        fn new(slots: usize, threads: usize) -> Fake {
            Fake {
                capacity: Capacity { slots, threads },
                queued: Vec::new(),
                per_wait: 1,
                submitted: Vec::new(),
                most_in_flight: 0,
                cancelled: false,
                fail: None,
                newest_first: false,
            }
        }
    }

    impl Cluster for Fake {
        fn capacity(&self) -> Capacity {
            self.capacity
        }
        fn submit(&mut self, id: usize, task: Vec<u8>) -> Result<()> {
            self.queued.push((id, decode(&task)?));
            self.submitted.push(id);
            self.most_in_flight = self.most_in_flight.max(self.queued.len());
            Ok(())
        }
        fn wait(&mut self, _: Duration) -> Result<Vec<(usize, Vec<u8>)>> {
            let mut out = Vec::new();
            for _ in 0..self.per_wait.min(self.queued.len()) {
                let (id, task) = match self.newest_first {
                    true => self.queued.pop().unwrap(),
                    false => self.queued.remove(0),
                };
                let outcome = match &self.fail {
                    Some((bad, f)) if *bad == id => f.clone(),
                    _ => Outcome::Done(task.cells.iter().map(result).collect()),
                };
                out.push((id, encode(&outcome)?));
            }
            Ok(out)
        }
        fn cancel(&mut self) {
            self.cancelled = true;
            self.queued.clear();
        }
    }

    /// Keeps what it was handed; stops after `stop_after` chunks.
    #[derive(Default)]
    struct Kept {
        chunks: Vec<Vec<CellResult>>,
        steps: u64,
        stop_after: Option<usize>,
    }

    impl Hooks for Kept {
        fn progress(&mut self, steps: u64) {
            self.steps += steps;
        }
        fn should_stop(&mut self) -> bool {
            self.stop_after.is_some_and(|n| self.chunks.len() >= n)
        }
        fn chunk_done(&mut self, results: &[CellResult]) -> Result<()> {
            self.chunks.push(results.to_vec());
            Ok(())
        }
    }

    fn job() -> Job {
        Job {
            config: SweepConfig::default(),
            model_sha256: "abc".into(),
            pupper_version: "0.1.0".into(),
            mujoco_version: "4.0.0".into(),
            chunk_steps: 250,
        }
    }

    #[test]
    fn addresses_are_auto_a_client_url_or_host_and_port() {
        for ok in [
            "auto",
            "ray://10.0.0.1:10001",
            "127.0.0.1:6379",
            "head.lab:6380",
        ] {
            assert_eq!(Address::parse(ok).unwrap().as_str(), ok);
        }
        for bad in [
            "",
            "head",
            "ray://head",
            "http://h:1",
            "h:port",
            "h:70000",
            ":6379",
        ] {
            let e = Address::parse(bad).unwrap_err().to_string();
            assert!(e.contains("is not a Ray address"), "{bad}: {e}");
        }
    }

    #[test]
    fn tasks_are_about_eight_per_slot_and_fill_their_threads() {
        let sizes = |n, slots, threads, reps, chunk| {
            tasks(&cells(n), Capacity { slots, threads }, reps, chunk)
                .iter()
                .map(Vec::len)
                .collect::<Vec<_>>()
        };
        // 256 cells on 2 slots: 16 tasks of 16
        assert_eq!(sizes(256, 2, 1, 1, None), vec![16; 16]);
        // a task has at least one simulation per thread
        assert_eq!(sizes(16, 4, 8, 1, None), vec![8, 8]);
        assert_eq!(sizes(16, 4, 8, 4, None), vec![2; 8]);
        // and at most DEFAULT_CHUNK_CELLS cells
        assert_eq!(sizes(2048, 1, 1, 1, None), vec![256; 8]);
        // --chunk-cells decides alone; the last task takes the rest
        assert_eq!(sizes(10, 2, 1, 1, Some(4)), vec![4, 4, 2]);
        // every cell once, in grid order
        let all: Vec<usize> = tasks(
            &cells(37),
            Capacity {
                slots: 3,
                threads: 2,
            },
            1,
            None,
        )
        .concat()
        .iter()
        .map(|c| c.index)
        .collect();
        assert_eq!(all, (0..37).collect::<Vec<_>>());
    }

    #[test]
    fn finished_tasks_are_handed_over_as_they_arrive_bit_for_bit() {
        let mut fake = Fake::new(2, 1);
        fake.newest_first = true;
        let mut kept = Kept::default();
        let cells = cells(24);
        run_cells(&mut fake, &job(), &cells, Some(5), &|_| 10, &mut kept).unwrap();
        // at most 2 per slot in flight, each task once
        assert!(fake.most_in_flight <= 4, "{}", fake.most_in_flight);
        assert_eq!(fake.submitted, vec![0, 1, 2, 3, 4]);
        // every cell came back once, its numbers bit for bit (NaN, -0, inf)
        let mut got: Vec<CellResult> = kept.chunks.concat();
        assert_ne!(got[0].cell.index, 0, "handed over as they finished");
        got.sort_by_key(|r| r.cell.index);
        assert_eq!(got.len(), 24);
        for (r, c) in got.iter().zip(&cells) {
            let want = result(c);
            assert_eq!(r.cell, want.cell);
            assert_eq!(format!("{:?}", r.metrics), format!("{:?}", want.metrics));
            assert_eq!(r.metrics.push_dip_mm.to_bits(), (-0.0f64).to_bits());
        }
        assert_eq!(kept.steps, 24 * 10);
        assert!(!fake.cancelled);
    }

    #[test]
    fn a_stop_cancels_what_runs_and_keeps_what_came_back() {
        let mut fake = Fake::new(1, 1);
        let mut kept = Kept {
            stop_after: Some(2),
            ..Kept::default()
        };
        let e = run_cells(&mut fake, &job(), &cells(10), Some(2), &|_| 1, &mut kept).unwrap_err();
        assert!(matches!(e, Error::Interrupted(_)));
        // two before the stop, and the one that finished meanwhile
        assert_eq!(kept.chunks.len(), 3);
        assert!(fake.cancelled);
    }

    #[test]
    fn a_worker_refusal_is_one_user_error_naming_the_node() {
        let mut fake = Fake::new(1, 1);
        // task 1 fails; task 0, back in the same wait, is still written
        fake.per_wait = 2;
        fake.fail = Some((
            1,
            Outcome::Failed {
                host: "node7".into(),
                user: true,
                message: "model file 'm.xml' does not exist".into(),
            },
        ));
        let mut kept = Kept::default();
        let e = run_cells(&mut fake, &job(), &cells(3), Some(1), &|_| 1, &mut kept).unwrap_err();
        assert_eq!(kept.chunks.len(), 1);
        assert_eq!(kept.chunks[0][0].cell.index, 0);
        assert!(matches!(e, Error::Cluster(_)));
        assert_eq!(
            e.to_string(),
            "on node node7: model file 'm.xml' does not exist"
        );
        assert!(fake.cancelled);
    }
}
