//! The thread pool every computation runs in, sized from Python.

use std::sync::{Arc, Mutex};

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use rayon::{ThreadPool, ThreadPoolBuilder};

static POOL: Mutex<Option<Arc<ThreadPool>>> = Mutex::new(None);

/// Most threads per core `set_num_threads` starts. Results do not depend on the thread
/// count, so more threads than cores only helps where cores are hidden from the process;
/// past this a typo (`10**6`) would start a million threads (load average 400 on 2 cores).
pub const MAX_THREADS_PER_CORE: usize = 64;

/// The most threads `set_num_threads` accepts: `MAX_THREADS_PER_CORE` per core the
/// process may use (`std::thread::available_parallelism`, 1 if unknown).
pub fn max_threads() -> usize {
    MAX_THREADS_PER_CORE * std::thread::available_parallelism().map_or(1, |n| n.get())
}

/// Use `n` worker threads from now on (`1 <= n <= 64 x cores`). Results do not depend on `n`.
#[pyfunction]
pub fn set_num_threads(n: i64) -> PyResult<()> {
    // Signed, so that -1 gets this message rather than pyo3's OverflowError.
    if n < 1 {
        return Err(PyValueError::new_err(format!(
            "the number of threads must be at least 1, got {n}"
        )));
    }
    let limit = max_threads();
    let n = usize::try_from(n).unwrap_or(usize::MAX);
    if n > limit {
        return Err(PyValueError::new_err(format!(
            "the number of threads must be at most {limit} ({MAX_THREADS_PER_CORE} per core, \
             {} cores available), got {n}",
            limit / MAX_THREADS_PER_CORE
        )));
    }
    let pool = ThreadPoolBuilder::new()
        .num_threads(n)
        .build()
        .map_err(|e| PyRuntimeError::new_err(format!("cannot start {n} threads: {e}")))?;
    let mut slot = POOL
        .lock()
        .map_err(|_| PyRuntimeError::new_err("thread pool lock poisoned"))?;
    *slot = Some(Arc::new(pool));
    Ok(())
}

/// Number of worker threads computations use.
#[pyfunction]
pub fn get_num_threads() -> usize {
    current().map_or_else(rayon::current_num_threads, |p| p.current_num_threads())
}

/// The pool set by `set_num_threads`, else one of rayon's default size (`RAYON_NUM_THREADS`
/// or the number of cores), made on first use.
fn current() -> Option<Arc<ThreadPool>> {
    let mut slot = POOL.lock().ok()?;
    if slot.is_none() {
        *slot = ThreadPoolBuilder::new().build().ok().map(Arc::new);
    }
    slot.clone()
}

/// Run `f` on a worker thread of the pool. From a worker, each parallel step of `f` is a
/// cheap fork; from the Python thread it would be a hand-off to the pool and back (futex
/// wake and wait): a quarter of a Newton CVT of 1,000 sites went to that.
pub fn run<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    match current() {
        Some(pool) => pool.install(f),
        None => f(),
    }
}

/// [`run`] when `parallel` (the core's answer: whether the work runs in parallel), else
/// `f` on the calling thread, where a little work costs less than the hand-off.
pub fn run_if<T: Send>(parallel: bool, f: impl FnOnce() -> T + Send) -> T {
    if parallel {
        run(f)
    } else {
        f()
    }
}
