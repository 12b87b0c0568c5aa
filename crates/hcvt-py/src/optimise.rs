//! CVTs as numpy arrays: `cvt` runs the whole iteration in the core with
//! the GIL released; the calling thread checks for Ctrl-C meanwhile, and the GIL is taken
//! once per iteration only when there is a callback to call. `check_settings` checks a
//! CVT's settings for every driver; the steps of a partitioned run are in `steps.rs`.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

use hcvt_core::{
    capacity_cvt, cvt as core_cvt, CapacityRecord, CapacitySettings, ConvexCell, DomainKind,
    Euclid, Frame, Named, Outcome, Record, Settings, Space, DEFAULT_VOLUME_TOL,
};
use numpy::{PyArray1, PyReadonlyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2};
use crate::density::{Coefficients, Given};
use crate::diagram::diagram_dict;
use crate::domain::{by_kind, AnyDomain};
use crate::errors::to_py_err;

/// CVT of `sites` (n, d) in `domain` (see `hcvt.cvt`): a dict with `sites`, `diagram` (the
/// arrays of `voronoi`), `history` (a dict of per-iterate arrays), `stop_reason`.
/// `callback(record)`, if given, gets a dict per iterate; a true return value stops.
/// With `volumes` (n,): the capacity-constrained CVT (`hcvt_core::capacity_cvt`, method
/// "lloyd"), every cell's volume within `volume_tol` (default 1e-8) of its target, scaled
/// to the domain's when `normalise`; the dict also has `weights` and `targets` (n,), and
/// the history `max_volume_error` and `newton_steps`. With `fixed` (n,) bool: the sites
/// flagged stay where they are (`Settings::fixed`).
#[pyfunction]
#[pyo3(signature = (domain, sites, method="lbfgs", rule="gap", tol=None, max_iter=10_000, memory=7, callback=None, polynomial=None, function=None, quadrature_degree=4, frame=None, volumes=None, normalise=false, volume_tol=None, fixed=None))]
#[allow(clippy::too_many_arguments)]
pub fn cvt<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    method: &str,
    rule: &str,
    tol: Option<f64>,
    max_iter: i64,
    memory: i64,
    callback: Option<Py<PyAny>>,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
    frame: Option<(Vec<f64>, f64)>,
    volumes: Option<PyReadonlyArray1<'py, f64>>,
    normalise: bool,
    volume_tol: Option<f64>,
    fixed: Option<PyReadonlyArray1<'py, bool>>,
) -> PyResult<Bound<'py, PyDict>> {
    let named = Named::parse(method, rule, tol, max_iter, memory).map_err(to_py_err)?;
    let volumes = volumes.map(|v| Volumes {
        values: v.as_array().to_vec(),
        normalise,
        tol: volume_tol.unwrap_or(DEFAULT_VOLUME_TOL),
    });
    let job = Job {
        named: &named,
        frame: frame.map_or(Ok(Frame::default()), to_frame)?,
        callback,
        given: &Given::new(polynomial, function, quadrature_degree)?,
        volumes,
        fixed: fixed.map(|f| f.as_array().to_vec()),
    };
    by_kind!(domain, run(py, &sites, job))
}

/// The settings of a CVT, checked by the core once for every driver (`hcvt.cvt`, the
/// partitioned run): the tolerance to use, the rule's default when `tol` is None.
#[pyfunction]
#[pyo3(signature = (method, rule, tol, max_iter, memory))]
pub fn check_settings(
    method: &str,
    rule: &str,
    tol: Option<f64>,
    max_iter: i64,
    memory: i64,
) -> PyResult<f64> {
    let named = Named::parse(method, rule, tol, max_iter, memory).map_err(to_py_err)?;
    Ok(named.tol)
}

/// `(centre (d,), scale)` of `hcvt.geometry.frame.Frame`, checked.
fn to_frame((centre, scale): (Vec<f64>, f64)) -> PyResult<Frame> {
    if centre.len() > 3
        || !(scale > 0.0 && scale.is_finite())
        || !centre.iter().all(|c| c.is_finite())
    {
        return Err(PyValueError::new_err(format!(
            "frame must be (centre of at most 3 finite values, scale > 0), got ({centre:?}, {scale})"
        )));
    }
    let mut out = Frame {
        scale,
        ..Frame::default()
    };
    for (slot, c) in out.centre.iter_mut().zip(centre) {
        *slot = c;
    }
    Ok(out)
}

/// What a CVT is asked besides its domain and sites.
struct Job<'a> {
    named: &'a Named,
    frame: Frame,
    callback: Option<Py<PyAny>>,
    given: &'a Given,
    /// Prescribed cell volumes: a capacity-constrained CVT.
    volumes: Option<Volumes>,
    /// Sites held still, one flag per site.
    fixed: Option<Vec<bool>>,
}

/// The volumes of a capacity-constrained CVT and how they are read.
struct Volumes {
    values: Vec<f64>,
    normalise: bool,
    tol: f64,
}

/// Most Newton steps of one transport in a capacity-constrained CVT (as
/// `hcvt.optimal_transport`'s default).
const TRANSPORT_MAX_ITER: usize = 100;

/// How often the waiting thread checks for Ctrl-C while the core works.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Run the core's loop on a worker inside the configured thread pool while this (the
/// calling, usually main) thread waits without the GIL and checks for signals every
/// `SIGNAL_POLL`: CPython runs signal handlers only on the main thread, so a check made by
/// a pool worker would never see Ctrl-C. A signal (or an error in the callback) stops the
/// loop at the next iterate and is raised here.
fn run<'py, const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    boundary: &K,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    job: Job<'_>,
) -> PyResult<Bound<'py, PyDict>>
where
    Euclid: Space<D>,
{
    let Job {
        named,
        frame,
        callback,
        given,
        volumes,
        fixed,
    } = job;
    let sites = rows::<f64, D>(sites, "sites")?;
    let density = given.density::<D>()?;
    let settings = Settings {
        frame,
        fixed: fixed.as_deref(),
        ..named.settings(density.as_ref())
    };
    let settings = &settings;
    let stop = AtomicBool::new(false);
    let raised: Mutex<Option<PyErr>> = Mutex::new(None);
    let raise = |err: PyErr| {
        stop.store(true, Ordering::Relaxed);
        if let Ok(mut slot) = raised.lock() {
            slot.get_or_insert(err);
        }
    };
    let mut observer = |record: &Record, sites: &[[f64; D]]| -> ControlFlow<()> {
        if let Some(callback) = &callback {
            match Python::attach(|py| call(py, callback, record, sites)) {
                Ok(true) => return ControlFlow::Break(()),
                Ok(false) => {}
                Err(err) => raise(err),
            }
        }
        if stop.load(Ordering::Relaxed) {
            ControlFlow::Break(())
        } else {
            ControlFlow::Continue(())
        }
    };
    let outcome = py.detach(|| {
        std::thread::scope(|scope| {
            let (done, finished) = mpsc::channel();
            let observer = &mut observer;
            let worker = scope.spawn(move || {
                let outcome = crate::threads::run(|| match &volumes {
                    None => core_cvt::<D, C, _>(boundary, sites, settings, observer)
                        .map(|outcome| (outcome, None)),
                    Some(v) => {
                        let asked = CapacitySettings {
                            cvt: *settings,
                            volume_tol: v.tol,
                            normalise: v.normalise,
                            transport_max_iter: TRANSPORT_MAX_ITER,
                        };
                        capacity_cvt::<D, C, _>(boundary, sites, &v.values, &asked, observer).map(
                            |c| {
                                let extra = (c.weights, c.targets, c.transport);
                                (c.outcome, Some(extra))
                            },
                        )
                    }
                });
                // The receiver lives until the worker is joined; a send cannot fail.
                let _ = done.send(outcome);
            });
            let result = loop {
                match finished.recv_timeout(SIGNAL_POLL) {
                    Ok(outcome) => break Ok(outcome),
                    Err(RecvTimeoutError::Timeout) => {
                        if let Err(err) = Python::attach(|py| py.check_signals()) {
                            raise(err);
                        }
                    }
                    Err(RecvTimeoutError::Disconnected) => {
                        break Err(PyRuntimeError::new_err("the CVT worker thread panicked"))
                    }
                }
            };
            // Joined by hand, a panic stays here instead of unwinding out of the scope.
            let _ = worker.join();
            result
        })
    })?;
    if let Some(err) = raised.into_inner().ok().flatten() {
        return Err(err);
    }
    let (outcome, capacity) = outcome.map_err(|e| given.error(e))?;
    let out = outcome_dict(py, outcome)?;
    if let Some(c) = capacity {
        capacity_items(py, &out, c)?;
    }
    Ok(out)
}

/// A capacity-constrained CVT's weights, targets and per-iteration transport columns.
fn capacity_items(
    py: Python<'_>,
    out: &Bound<'_, PyDict>,
    (weights, targets, transport): (Vec<f64>, Vec<f64>, Vec<CapacityRecord>),
) -> PyResult<()> {
    out.set_item("weights", PyArray1::from_vec(py, weights))?;
    out.set_item("targets", PyArray1::from_vec(py, targets))?;
    let history = out
        .get_item("history")?
        .ok_or_else(|| PyRuntimeError::new_err("the CVT's dict has no history"))?;
    let errors = transport.iter().map(|r| r.max_volume_error);
    history.set_item("max_volume_error", PyArray1::from_iter(py, errors))?;
    let steps: Vec<usize> = transport.iter().map(|r| r.newton_steps).collect();
    history.set_item("newton_steps", crate::arrays::to_intp(py, &steps)?)?;
    Ok(())
}

/// Call the callback with a dict of the iterate; `true` (a true return value) asks to stop.
fn call<const D: usize>(
    py: Python<'_>,
    callback: &Py<PyAny>,
    record: &Record,
    sites: &[[f64; D]],
) -> PyResult<bool> {
    let info = PyDict::new(py);
    info.set_item("energy", record.energy)?;
    info.set_item("mean_G", record.mean_g)?;
    info.set_item("rms_gap", record.measures.rms_gap)?;
    info.set_item("max_gap", record.measures.max_gap)?;
    info.set_item("grad_norm", record.measures.grad_norm)?;
    info.set_item("pinned", record.measures.pinned)?;
    info.set_item("seconds", record.seconds)?;
    info.set_item("evaluations", record.evaluations)?;
    info.set_item("step", record.step.as_str())?;
    info.set_item("sites", to_array2(py, sites)?)?;
    callback.bind(py).call1((info,))?.is_truthy()
}

fn outcome_dict<const D: usize>(
    py: Python<'_>,
    mut outcome: Outcome<D>,
) -> PyResult<Bound<'_, PyDict>> {
    let h = &outcome.history;
    let column = |f: fn(&Record) -> f64| PyArray1::from_iter(py, h.iter().map(f));
    let history = PyDict::new(py);
    history.set_item("energy", column(|r| r.energy))?;
    history.set_item("mean_G", column(|r| r.mean_g))?;
    history.set_item("rms_gap", column(|r| r.measures.rms_gap))?;
    history.set_item("max_gap", column(|r| r.measures.max_gap))?;
    history.set_item("grad_norm", column(|r| r.measures.grad_norm))?;
    let pinned: Vec<usize> = h.iter().map(|r| r.measures.pinned).collect();
    history.set_item("pinned", crate::arrays::to_intp(py, &pinned)?)?;
    history.set_item("seconds", column(|r| r.seconds))?;
    let evaluations: Vec<usize> = h.iter().map(|r| r.evaluations).collect();
    history.set_item("evaluations", crate::arrays::to_intp(py, &evaluations)?)?;
    let steps: Vec<&str> = h.iter().map(|r| r.step.as_str()).collect();
    history.set_item("step", steps)?;
    let out = PyDict::new(py);
    out.set_item("sites", to_array2(py, &outcome.sites)?)?;
    out.set_item(
        "diagram",
        diagram_dict(py, std::mem::take(&mut outcome.diagram))?,
    )?;
    out.set_item("history", history)?;
    out.set_item("stop_reason", outcome.stop_reason.as_str())?;
    out.set_item("iterations", outcome.iterations())?;
    out.set_item("evaluations", outcome.evaluations())?;
    Ok(out)
}
