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

fn current() -> Option<Arc<ThreadPool>> {
    POOL.lock().ok().and_then(|slot| slot.clone())
}

/// Run `f` in the configured pool (rayon's global pool until `set_num_threads` is called).
pub fn run<T: Send>(f: impl FnOnce() -> T + Send) -> T {
    match current() {
        Some(pool) => pool.install(f),
        None => f(),
    }
}
