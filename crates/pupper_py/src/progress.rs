//! A running sweep seen from Python: progress to a callable, Ctrl-C, and
//! the interpreter's exit, which stops sweeps still running in threads.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::{Duration, Instant};

use pyo3::exceptions::PyKeyboardInterrupt;
use pyo3::prelude::*;

use pupper_core::sim::runner::Hooks;
use pupper_mujoco::api::SweepUi;

/// Set when the interpreter exits (`_shutdown`, from an `atexit` hook): a
/// sweep still running in another thread then stops at its next check,
/// keeps what it finished, and leaves Rust before Python finalizes (a
/// daemon thread woken inside Rust after that would be torn down mid-call).
static SHUTDOWN: AtomicBool = AtomicBool::new(false);
/// Sweeps running now, in any thread.
static ACTIVE: AtomicUsize = AtomicUsize::new(0);
/// The longest the exit waits for running sweeps to stop (s).
const SHUTDOWN_WAIT: f64 = 30.0;

/// Counts a running sweep while it lives.
pub(crate) struct Active;

impl Active {
    /// Counts a sweep about to start; none starts once the interpreter is
    /// exiting. Counted before that check, so an exit from then on waits.
    pub(crate) fn start() -> PyResult<Active> {
        ACTIVE.fetch_add(1, Ordering::SeqCst);
        let active = Active;
        if SHUTDOWN.load(Ordering::SeqCst) {
            return Err(PyKeyboardInterrupt::new_err(
                "the interpreter is exiting: no new sweep starts",
            ));
        }
        Ok(active)
    }
}

impl Drop for Active {
    fn drop(&mut self) {
        ACTIVE.fetch_sub(1, Ordering::SeqCst);
    }
}

/// The interpreter is exiting: asks running sweeps to stop and waits (the
/// GIL released) until they have left Rust, at most `SHUTDOWN_WAIT` s.
#[pyfunction]
pub(crate) fn _shutdown(py: Python<'_>) {
    SHUTDOWN.store(true, Ordering::SeqCst);
    let started = Instant::now();
    while ACTIVE.load(Ordering::SeqCst) > 0 && started.elapsed().as_secs_f64() < SHUTDOWN_WAIT {
        py.detach(|| std::thread::sleep(Duration::from_millis(10)));
    }
}

/// Progress to a Python callable, throttled; Ctrl-C through check_signals.
pub(crate) struct PyUi<'py> {
    py: Python<'py>,
    callback: Option<Bound<'py, PyAny>>,
    done: u64,
    total: u64,
    last: Instant,
    interrupt: Option<PyErr>,
    failed: Option<PyErr>,
}

impl<'py> PyUi<'py> {
    /// Progress to `callback(done_steps, total_steps)`, if any.
    pub(crate) fn new(py: Python<'py>, callback: Option<Bound<'py, PyAny>>) -> Self {
        PyUi {
            py,
            callback,
            done: 0,
            total: 0,
            last: Instant::now(),
            interrupt: None,
            failed: None,
        }
    }

    /// What stopped the sweep from Python's side: the callback's own
    /// exception first, then Ctrl-C or the interpreter's exit.
    pub(crate) fn stopped(self) -> PyResult<()> {
        match (self.failed, self.interrupt) {
            (Some(e), _) | (None, Some(e)) => Err(e),
            (None, None) => Ok(()),
        }
    }

    fn report(&mut self) {
        if let Some(cb) = &self.callback
            && let Err(e) = cb.call1((self.done, self.total))
        {
            self.failed.get_or_insert(e);
        }
        self.last = Instant::now();
    }
}

impl SweepUi for PyUi<'_> {
    fn start(&mut self, _cells: usize, steps: u64) {
        self.total = steps;
        self.report();
    }
    fn finish(&mut self) {
        self.done = self.total;
        self.report();
    }
    fn hooks(&mut self) -> &mut dyn Hooks {
        self
    }
}

impl Hooks for PyUi<'_> {
    fn progress(&mut self, steps: u64) {
        self.done += steps;
        if self.last.elapsed() > Duration::from_millis(200) {
            self.report();
        }
    }
    fn should_stop(&mut self) -> bool {
        if self.failed.is_some() {
            return true;
        }
        if SHUTDOWN.load(Ordering::SeqCst) {
            self.interrupt.get_or_insert_with(|| {
                PyKeyboardInterrupt::new_err(
                    "the interpreter is exiting: sweep stopped; finished cells are kept (resume=True continues a run directory)",
                )
            });
            return true;
        }
        if let Err(e) = self.py.check_signals() {
            self.interrupt = Some(e);
            return true;
        }
        false
    }
}
