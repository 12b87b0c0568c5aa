//! CVTs as numpy arrays: `cvt_2d` and `cvt_3d` run the whole iteration in the core with
//! the GIL released; the calling thread checks for Ctrl-C meanwhile, and the GIL is taken
//! once per iteration only when there is a callback to call.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

use hcvt_core::diagram::{ConvexCell, PolygonCell, PolyhedronCell};
use hcvt_core::domain::{Boundary, WindingNumber};
use hcvt_core::geometry::{Euclid, Space};
use hcvt_core::optimise::{cvt_with_density, Frame, Method, Outcome, Record, Rule, Settings};
use numpy::{PyArray1, PyReadonlyArray2};
use pyo3::exceptions::{PyRuntimeError, PyValueError};
use pyo3::prelude::*;
use pyo3::types::PyDict;

use crate::arrays::{rows, to_array2};
use crate::density::{Coefficients, Given};
use crate::diagram::diagram_dict;
use crate::domain::{PolygonDomain, SolidDomain};

/// CVT of `sites` (n, 2) in `domain` (see `hcvt.cvt`): a dict with `sites`, `diagram` (the
/// arrays of `voronoi_2d`), `history` (a dict of per-iterate arrays), `stop_reason`.
/// `callback(record)`, if given, gets a dict per iterate; a true return value stops.
#[pyfunction]
#[pyo3(signature = (domain, sites, method="lbfgs", rule="gap", tol=None, max_iter=10_000, memory=7, callback=None, polynomial=None, function=None, quadrature_degree=4, frame=None))]
#[allow(clippy::too_many_arguments)]
pub fn cvt_2d<'py>(
    py: Python<'py>,
    domain: &PolygonDomain,
    sites: PyReadonlyArray2<'py, f64>,
    method: &str,
    rule: &str,
    tol: Option<f64>,
    max_iter: usize,
    memory: usize,
    callback: Option<Py<PyAny>>,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
    frame: Option<(Vec<f64>, f64)>,
) -> PyResult<Bound<'py, PyDict>> {
    let settings = settings(method, rule, tol, max_iter, memory, frame)?;
    let points = rows::<f64, 2>(&sites, "sites")?;
    let given = Given::new(polynomial, function, quadrature_degree)?;
    run::<2, PolygonCell>(py, &domain.0, points, &settings, callback, &given)
}

/// CVT of `sites` (n, 3) in the solid `domain`; as `cvt_2d`.
#[pyfunction]
#[pyo3(signature = (domain, sites, method="lbfgs", rule="gap", tol=None, max_iter=10_000, memory=7, callback=None, polynomial=None, function=None, quadrature_degree=4, frame=None))]
#[allow(clippy::too_many_arguments)]
pub fn cvt_3d<'py>(
    py: Python<'py>,
    domain: &SolidDomain,
    sites: PyReadonlyArray2<'py, f64>,
    method: &str,
    rule: &str,
    tol: Option<f64>,
    max_iter: usize,
    memory: usize,
    callback: Option<Py<PyAny>>,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
    frame: Option<(Vec<f64>, f64)>,
) -> PyResult<Bound<'py, PyDict>> {
    let settings = settings(method, rule, tol, max_iter, memory, frame)?;
    let points = rows::<f64, 3>(&sites, "sites")?;
    let given = Given::new(polynomial, function, quadrature_degree)?;
    run::<3, PolyhedronCell>(py, &domain.0, points, &settings, callback, &given)
}

fn settings(
    method: &str,
    rule: &str,
    tol: Option<f64>,
    max_iter: usize,
    memory: usize,
    frame: Option<(Vec<f64>, f64)>,
) -> PyResult<Settings> {
    let method = match method {
        "lbfgs" => Method::Lbfgs,
        "lloyd" => Method::Lloyd,
        "newton" => Method::Newton,
        other => {
            return Err(PyValueError::new_err(format!(
                "method must be 'lbfgs', 'lloyd' or 'newton', got {other:?}"
            )))
        }
    };
    let rule = match rule {
        "gap" => Rule::Gap,
        "paper" => Rule::Paper,
        other => {
            return Err(PyValueError::new_err(format!(
                "rule must be 'gap' or 'paper', got {other:?}"
            )))
        }
    };
    let tol = tol.unwrap_or_else(|| rule.default_tol());
    if tol.is_nan() || tol < 0.0 {
        return Err(PyValueError::new_err(format!(
            "tol must be a number >= 0, got {tol}"
        )));
    }
    Ok(Settings {
        method,
        rule,
        tol,
        max_iter,
        memory,
        frame: frame.map_or(Ok(Frame::default()), to_frame)?,
        ..Settings::default()
    })
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

/// How often the waiting thread checks for Ctrl-C while the core works.
const SIGNAL_POLL: Duration = Duration::from_millis(50);

/// Run the core's loop on a worker inside the configured thread pool while this (the
/// calling, usually main) thread waits without the GIL and checks for signals every
/// `SIGNAL_POLL`: CPython runs signal handlers only on the main thread, so a check made by
/// a pool worker would never see Ctrl-C. A signal (or an error in the callback) stops the
/// loop at the next iterate and is raised here.
fn run<'py, const D: usize, C: ConvexCell<D>>(
    py: Python<'py>,
    boundary: &Boundary<D>,
    sites: Vec<[f64; D]>,
    settings: &Settings,
    callback: Option<Py<PyAny>>,
    given: &Given,
) -> PyResult<Bound<'py, PyDict>>
where
    Euclid: Space<D> + WindingNumber<D>,
{
    let density = given.density::<D>()?;
    let density = density.as_ref();
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
                let outcome = crate::threads::run(|| {
                    cvt_with_density::<D, C>(boundary, sites, settings, density, observer)
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
    outcome_dict(py, &outcome.map_err(|e| given.error(e))?)
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

fn outcome_dict<'py, const D: usize>(
    py: Python<'py>,
    outcome: &Outcome<D>,
) -> PyResult<Bound<'py, PyDict>> {
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
        diagram_dict(py, &outcome.diagram, &outcome.sites)?,
    )?;
    out.set_item("history", history)?;
    out.set_item("stop_reason", outcome.stop_reason.as_str())?;
    out.set_item("iterations", outcome.iterations())?;
    out.set_item("evaluations", outcome.evaluations())?;
    Ok(out)
}
