//! CVTs as numpy arrays: `cvt` runs the whole iteration in the core with
//! the GIL released; the calling thread checks for Ctrl-C meanwhile, and the GIL is taken
//! once per iteration only when there is a callback to call.
//!
//! The steps of one part of a partitioned run (`hcvt.partition`, `hcvt.distributed`) are
//! the core's too: its Lloyd step and guards, the L-BFGS coefficients, direction and
//! acceptance, and the check of the settings.

use std::ops::ControlFlow;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError};
use std::sync::Mutex;
use std::time::Duration;

use hcvt_core::lbfgs::{self, LineSearch};
use hcvt_core::{
    capacity_cvt, cvt as core_cvt, lloyd, optimal_transport as core_transport, CapacityRecord,
    CapacitySettings, ConvexCell, DomainKind, Euclid, Frame, Moments, Named, Outcome, Record,
    Settings, Space, TransportRecord, TransportSettings, DEFAULT_VOLUME_TOL,
};
use numpy::{
    PyArray1, PyArray2, PyReadonlyArray1, PyReadonlyArray2, PyReadonlyArray3, PyUntypedArrayMethods,
};
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

/// What a part's next step needs from its cells (`hcvt.distributed.partition`): the shift
/// to the centroid (k, d) (0 for an empty cell), whether each site is pinned (k,), and the
/// preconditioner `1/(2 m_i)` (k,), each by the core's Lloyd and L-BFGS.
#[pyfunction]
pub fn step_fields<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    mass: PyReadonlyArray1<'py, f64>,
    first: PyReadonlyArray2<'py, f64>,
    boundary_measure: PyReadonlyArray1<'py, f64>,
) -> PyResult<StepFields<'py>> {
    by_kind!(domain, dim step_fields_in(py, &sites, &mass, &first, &boundary_measure))
}

/// The core's Lloyd step of `sites` (k, d) by `shifts` (k, d), held inside.
#[pyfunction]
pub fn lloyd_step<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    shifts: PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    by_kind!(domain, dim lloyd_step_in(py, &sites, &shifts))
}

/// One part's rows (k, d) of the L-BFGS direction from the coefficients of
/// `lbfgs_coefficients`, held inside: `gradient` (k, d), pairs `s` and `y` (m, k, d) oldest
/// first, `preconditioner` (k,).
#[pyfunction]
#[allow(clippy::too_many_arguments)]
pub fn lbfgs_direction<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    gradient: PyReadonlyArray2<'py, f64>,
    s: PyReadonlyArray3<'py, f64>,
    y: PyReadonlyArray3<'py, f64>,
    preconditioner: PyReadonlyArray1<'py, f64>,
    c: PyReadonlyArray1<'py, f64>,
    e: PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>> {
    let part = PartPairs {
        sites: &sites,
        gradient: &gradient,
        s: &s,
        y: &y,
        preconditioner: &preconditioner,
    };
    by_kind!(domain, dim lbfgs_direction_in(py, part, &c, &e))
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

/// The coefficients `(c, e)` of the L-BFGS direction from the Gram matrices `plain` and
/// `weighted` (2m+1, 2m+1) of `[s, y, g]`, summed over the parts: the core's two-loop
/// recursion in coefficient space.
#[pyfunction]
pub fn lbfgs_coefficients<'py>(
    py: Python<'py>,
    plain: PyReadonlyArray2<'py, f64>,
    weighted: PyReadonlyArray2<'py, f64>,
) -> PyResult<Coefficients2<'py>> {
    let (c, e) =
        lbfgs::gram_coefficients(plain.as_slice()?, weighted.as_slice()?).map_err(to_py_err)?;
    Ok((PyArray1::from_vec(py, c), PyArray1::from_vec(py, e)))
}

/// Whether the partitioned run's backtracking line search accepts the step `t` with
/// energy `value` and slope `slope` from `phi0`, `slope0` (the core's acceptance).
#[pyfunction]
pub fn line_search_accepts(phi0: f64, slope0: f64, t: f64, value: f64, slope: f64) -> bool {
    LineSearch::backtracking(1).accepts(phi0, slope0, t, value, slope)
}

/// Whether an L-BFGS pair with these products is kept (the core's curvature test).
#[pyfunction]
pub fn positive_curvature(sy: f64, ss: f64, yy: f64) -> bool {
    lbfgs::positive_curvature(sy, ss, yy)
}

/// `c` (m + 1,) and `e` (m,).
type Coefficients2<'py> = (Bound<'py, PyArray1<f64>>, Bound<'py, PyArray1<f64>>);

/// Shifts (k, d), pinned (k,), preconditioner (k,).
type StepFields<'py> = (
    Bound<'py, PyArray2<f64>>,
    Bound<'py, PyArray1<bool>>,
    Bound<'py, PyArray1<f64>>,
);

fn values(array: &PyReadonlyArray1<'_, f64>, n: usize, what: &str) -> PyResult<Vec<f64>> {
    let out = array.as_slice()?.to_vec();
    if out.len() != n {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape ({n},), got {:?}",
            array.shape()
        )));
    }
    Ok(out)
}

fn step_fields_in<'py, const D: usize, K: DomainKind<D>>(
    boundary: &K,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    mass: &PyReadonlyArray1<'py, f64>,
    first: &PyReadonlyArray2<'py, f64>,
    boundary_measure: &PyReadonlyArray1<'py, f64>,
) -> PyResult<StepFields<'py>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(sites, "sites")?;
    let n = points.len();
    let mass = values(mass, n, "mass")?;
    let first = rows::<f64, D>(first, "first")?;
    let measure = values(boundary_measure, n, "boundary_measure")?;
    if first.len() != n {
        return Err(PyValueError::new_err("first must have one row per site"));
    }
    let moments: Vec<Moments<D>> = (mass.iter().zip(&first))
        .map(|(&mass, &first)| Moments {
            mass,
            first,
            second: 0.0,
        })
        .collect();
    let shifts = lloyd::centroid_shifts(&moments);
    let pinned = py.detach(|| lloyd::pinned(boundary, &points, &shifts, &measure));
    let shifts: Vec<[f64; D]> = shifts.iter().map(|s| s.unwrap_or([0.0; D])).collect();
    Ok((
        to_array2(py, &shifts)?,
        PyArray1::from_vec(py, pinned),
        PyArray1::from_vec(py, lbfgs::preconditioner(mass)),
    ))
}

fn lloyd_step_in<'py, const D: usize, K: DomainKind<D>>(
    boundary: &K,
    py: Python<'py>,
    sites: &PyReadonlyArray2<'py, f64>,
    shifts: &PyReadonlyArray2<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(sites, "sites")?;
    let shifts = rows::<f64, D>(shifts, "shifts")?;
    if shifts.len() != points.len() {
        return Err(PyValueError::new_err("shifts must have one row per site"));
    }
    let moved = py.detach(|| lloyd::lloyd_step(boundary, &points, &shifts));
    to_array2(py, &moved)
}

/// A part's sites and per-row L-BFGS state, as numpy arrays.
struct PartPairs<'a, 'py> {
    sites: &'a PyReadonlyArray2<'py, f64>,
    gradient: &'a PyReadonlyArray2<'py, f64>,
    s: &'a PyReadonlyArray3<'py, f64>,
    y: &'a PyReadonlyArray3<'py, f64>,
    preconditioner: &'a PyReadonlyArray1<'py, f64>,
}

/// An (m, k, D) array as m vectors of k rows.
fn pairs<const D: usize>(
    array: &PyReadonlyArray3<'_, f64>,
    k: usize,
    what: &str,
) -> PyResult<Vec<Vec<[f64; D]>>> {
    let shape = array.shape();
    if shape.get(1..) != Some(&[k, D][..]) {
        return Err(PyValueError::new_err(format!(
            "{what} must have shape (m, {k}, {D}), got {shape:?}"
        )));
    }
    let flat = array.as_slice()?;
    Ok(flat
        .chunks_exact((k * D).max(1))
        .map(|pair| {
            pair.chunks_exact(D)
                .filter_map(|row| <[f64; D]>::try_from(row).ok())
                .collect()
        })
        .collect())
}

fn lbfgs_direction_in<'py, const D: usize, K: DomainKind<D>>(
    boundary: &K,
    py: Python<'py>,
    part: PartPairs<'_, 'py>,
    c: &PyReadonlyArray1<'py, f64>,
    e: &PyReadonlyArray1<'py, f64>,
) -> PyResult<Bound<'py, PyArray2<f64>>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(part.sites, "sites")?;
    let k = points.len();
    let gradient = rows::<f64, D>(part.gradient, "gradient")?;
    let s = pairs::<D>(part.s, k, "s")?;
    let y = pairs::<D>(part.y, k, "y")?;
    if gradient.len() != k {
        return Err(PyValueError::new_err("gradient must have one row per site"));
    }
    let preconditioner = part.preconditioner.as_slice()?;
    let mut direction = lbfgs::combine(
        c.as_slice()?,
        e.as_slice()?,
        &gradient,
        &s,
        &y,
        preconditioner,
    )
    .map_err(to_py_err)?;
    py.detach(|| lloyd::hold_inside(boundary, &points, &mut direction));
    to_array2(py, &direction)
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

/// Semi-discrete optimal transport (see `hcvt.optimal_transport`): the weights of the power
/// diagram of `sites` (n, d) in `domain` whose cell i has mass `masses[i]` (with a density,
/// ∫ρ), by the core's damped Newton iteration. A dict with `weights` (n,), `diagram` (the
/// arrays of `voronoi` for those weights), `targets` (n,), `max_error`, `converged` and
/// `history` (per Newton step: `max_error`, `step`, `cg_iterations`, `diagrams`,
/// `min_mass`).
#[pyfunction]
#[pyo3(signature = (domain, sites, masses, tol=1e-10, max_iter=100, normalise=false, polynomial=None, function=None, quadrature_degree=4))]
#[allow(clippy::too_many_arguments)]
pub fn optimal_transport<'py>(
    py: Python<'py>,
    domain: AnyDomain<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    masses: PyReadonlyArray1<'py, f64>,
    tol: f64,
    max_iter: usize,
    normalise: bool,
    polynomial: Option<Coefficients>,
    function: Option<Py<PyAny>>,
    quadrature_degree: usize,
) -> PyResult<Bound<'py, PyDict>> {
    let given = Given::new(polynomial, function, quadrature_degree)?;
    let asked = Transported {
        masses: masses.as_array().to_vec(),
        tol,
        max_iter,
        normalise,
        given: &given,
    };
    by_kind!(domain, transport_in(py, sites, &asked))
}

/// What `optimal_transport` is asked for besides its domain and sites.
struct Transported<'a> {
    masses: Vec<f64>,
    tol: f64,
    max_iter: usize,
    normalise: bool,
    given: &'a Given,
}

fn transport_in<'py, const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    py: Python<'py>,
    sites: PyReadonlyArray2<'py, f64>,
    asked: &Transported<'_>,
) -> PyResult<Bound<'py, PyDict>>
where
    Euclid: Space<D>,
{
    let points = rows::<f64, D>(&sites, "sites")?;
    let density = asked.given.density::<D>()?;
    let settings = TransportSettings {
        tol: asked.tol,
        max_iter: asked.max_iter,
        density: density.as_ref(),
        normalise: asked.normalise,
    };
    let out = py
        .detach(|| {
            crate::threads::run(|| {
                core_transport::<D, C, K>(domain, &points, &asked.masses, &settings)
            })
        })
        .map_err(|e| asked.given.error(e))?;
    let result = PyDict::new(py);
    result.set_item("weights", PyArray1::from_vec(py, out.weights))?;
    result.set_item("diagram", diagram_dict(py, out.diagram)?)?;
    result.set_item("targets", PyArray1::from_vec(py, out.targets))?;
    result.set_item("max_error", out.max_error)?;
    result.set_item("converged", out.converged)?;
    let history = PyDict::new(py);
    let column =
        |f: fn(&TransportRecord) -> f64| -> Vec<f64> { out.history.iter().map(f).collect() };
    history.set_item("max_error", PyArray1::from_vec(py, column(|r| r.max_error)))?;
    history.set_item("step", PyArray1::from_vec(py, column(|r| r.step)))?;
    history.set_item("min_mass", PyArray1::from_vec(py, column(|r| r.min_mass)))?;
    let counts =
        |f: fn(&TransportRecord) -> usize| -> Vec<usize> { out.history.iter().map(f).collect() };
    history.set_item(
        "cg_iterations",
        PyArray1::from_vec(py, counts(|r| r.cg_iterations)),
    )?;
    history.set_item("diagrams", PyArray1::from_vec(py, counts(|r| r.diagrams)))?;
    result.set_item("history", history)?;
    Ok(result)
}
