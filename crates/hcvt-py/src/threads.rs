//! The thread pool every computation runs in, sized from Python.

use std::sync::{Arc, Mutex};

use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use rayon::{ThreadPool, ThreadPoolBuilder};

static POOL: Mutex<Option<Arc<ThreadPool>>> = Mutex::new(None);

/// Use `n` worker threads from now on (`n >= 1`). Results do not depend on `n`.
#[pyfunction]
pub fn set_num_threads(n: usize) -> PyResult<()> {
    if n == 0 {
        return Err(PyValueError::new_err(
            "the number of threads must be at least 1",
        ));
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
