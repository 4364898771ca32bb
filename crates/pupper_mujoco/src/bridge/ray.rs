//! The driver's side of `--ray`: a [`Cluster`] over `pupper_core._ray`,
//! which connects to Ray, keeps the job in its object store and runs tasks
//! there. What goes in a task and what is written when is the Rust core's
//! ([`pupper_core::sim::cluster`]); a worker runs [`crate::api::run_task`].

use std::time::Duration;

use pyo3::prelude::*;
use pyo3::types::PyBytes;

use super::python::{exception_name, python_message};
use pupper_core::error::{Error, Result};
use pupper_core::results::output::{RayNode, RayRecord};
use pupper_core::sim::cluster::{self, Address, Capacity, Cluster, Job};

/// The Python module that talks to Ray.
const MODULE: &str = "pupper_core._ray";

/// (host name, address, CPUs) of a node, as the driver reports it.
type NodeRow = (String, String, f64);

/// A connection to a Ray cluster, ready to run a job's tasks.
pub struct RayCluster<'py> {
    driver: Bound<'py, PyAny>,
    capacity: Capacity,
    pub record: RayRecord,
}

/// A Python error of the Ray module as one line: the user's to fix (Ray
/// missing, the cluster unreachable or unfit, a task lost for good), an
/// interrupt, or a bug.
fn ray_err(py: Python<'_>, e: PyErr) -> Error {
    if e.is_instance_of::<pyo3::exceptions::PyKeyboardInterrupt>(py) {
        return Error::Interrupted("KeyboardInterrupt".into());
    }
    let kind = exception_name(py, &e);
    let msg = python_message(py, &e);
    match kind.as_str() {
        "RayUnavailable" | "ClusterUnreachable" | "ClusterFailure" => Error::Cluster(msg),
        _ => Error::Internal(format!("ray driver: {kind}: {msg}")),
    }
}

impl<'py> RayCluster<'py> {
    /// Connects to the cluster at `address` and puts `job` there. Tasks
    /// take `threads` CPUs each (0: as many as the smallest node has) and
    /// `gpus` GPUs. Fails with one line when Ray is missing or the cluster
    /// cannot be reached.
    pub fn connect(
        py: Python<'py>,
        address: &Address,
        job: &Job,
        threads: usize,
        gpus: f64,
    ) -> Result<Self> {
        let module = PyModule::import(py, MODULE).map_err(|e| {
            Error::Mujoco(format!(
                "cannot import {MODULE} ({}): run `make setup` to install pupper's Python package",
                python_message(py, &e)
            ))
        })?;
        let job = cluster::encode(job)?;
        let _keep = KeepSignals::save();
        let driver = module
            .getattr("Driver")
            .and_then(|d| d.call1((address.as_str(), PyBytes::new(py, &job), threads, gpus)))
            .map_err(|e| ray_err(py, e))?;
        let asked = (|| -> PyResult<((usize, usize), Vec<NodeRow>)> {
            Ok((
                driver.call_method0("capacity")?.extract()?,
                driver.call_method0("nodes")?.extract()?,
            ))
        })();
        let ((slots, per_task), nodes) = asked.map_err(|e| {
            let _ = driver.call_method0("close");
            ray_err(py, e)
        })?;
        Ok(RayCluster {
            capacity: Capacity {
                slots,
                threads: per_task,
            },
            record: RayRecord {
                address: address.to_string(),
                nodes: nodes
                    .into_iter()
                    .map(|(host, address, cpus)| RayNode {
                        host,
                        address,
                        cpus,
                    })
                    .collect(),
                slots,
                threads_per_task: per_task,
            },
            driver,
        })
    }
}

/// `ray.init` takes SIGTERM for itself (exiting the interpreter on it),
/// which would leave a stop unhandled: Ctrl-C's and SIGTERM's handlers from
/// before the connection are put back when this drops.
struct KeepSignals {
    #[cfg(unix)]
    saved: Vec<(libc::c_int, libc::sigaction)>,
}

impl KeepSignals {
    fn save() -> KeepSignals {
        #[cfg(unix)]
        {
            let saved = [libc::SIGINT, libc::SIGTERM]
                .into_iter()
                .filter_map(|sig| {
                    // SAFETY: reads the current action into a zeroed struct
                    // of the right type; installs nothing.
                    let mut old: libc::sigaction = unsafe { std::mem::zeroed() };
                    let ok = unsafe { libc::sigaction(sig, std::ptr::null(), &mut old) } == 0;
                    ok.then_some((sig, old))
                })
                .collect();
            KeepSignals { saved }
        }
        #[cfg(not(unix))]
        KeepSignals {}
    }
}

impl Drop for KeepSignals {
    fn drop(&mut self) {
        #[cfg(unix)]
        for (sig, old) in &self.saved {
            // SAFETY: puts back an action read from the kernel by `save`.
            unsafe { libc::sigaction(*sig, old, std::ptr::null_mut()) };
        }
    }
}

impl Cluster for RayCluster<'_> {
    fn capacity(&self) -> Capacity {
        self.capacity
    }

    fn submit(&mut self, id: usize, task: Vec<u8>) -> Result<()> {
        let py = self.driver.py();
        self.driver
            .call_method1("submit", (id, PyBytes::new(py, &task)))
            .map(drop)
            .map_err(|e| ray_err(py, e))
    }

    fn wait(&mut self, timeout: Duration) -> Result<Vec<(usize, Vec<u8>)>> {
        let py = self.driver.py();
        let done: Vec<(usize, Bound<'_, PyBytes>)> = self
            .driver
            .call_method1("wait", (timeout.as_secs_f64(),))
            .and_then(|d| d.extract())
            .map_err(|e| ray_err(py, e))?;
        Ok(done
            .into_iter()
            .map(|(id, b)| (id, b.as_bytes().to_vec()))
            .collect())
    }

    fn cancel(&mut self) {
        // best effort: the tasks die with this driver anyway
        let _ = self.driver.call_method0("cancel");
    }
}

impl Drop for RayCluster<'_> {
    fn drop(&mut self) {
        let _ = self.driver.call_method0("close");
    }
}
