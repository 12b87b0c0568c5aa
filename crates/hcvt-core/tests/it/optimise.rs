//! CVT optimisation in the core: exact gradient, Lloyd's monotonicity, lattice fixed
//! points, convergence in a non-convex polygon, reseeding of empty cells.

use crate::common::{dented_cube, hessian_error, interior_sites, polygon};

use std::ops::ControlFlow;

use hcvt_core::lloyd::reseed_empty;
use hcvt_core::{
    clipped_diagram, cvt, evaluate, Boundary, CoreError, DomainKind, Euclid, Measures, Method,
    Options, Outcome, Point, PointRequest, Polygon, PolygonCell, PolyhedronCell, Request, Rule,
    Settings, Solid, Space, Step, StopReason, Surface,
};

/// An L-shaped polygon with a square hole: non-convex, and with a hole.
fn l_shape() -> Polygon {
    polygon(&[
        &[[0., 0.], [4., 0.], [4., 2.], [2., 2.], [2., 4.], [0., 4.]],
        &[[0.5, 0.5], [0.5, 1.0], [1.0, 1.0], [1.0, 0.5]],
    ])
}

/// The box `[lo, hi]` as 12 outward triangles.
fn cuboid(lo: [f64; 3], hi: [f64; 3]) -> Solid {
    Solid::cuboid(lo, hi).unwrap()
}

/// Cell centres of a `counts` grid over `[lo, hi]`.
fn grid<const D: usize>(counts: [usize; D], lo: [f64; D], hi: [f64; D]) -> Vec<[f64; D]> {
    let total: usize = counts.iter().product();
    (0..total)
        .map(|mut index| {
            std::array::from_fn(|k| {
                let i = index % counts[k];
                index /= counts[k];
                lo[k] + (i as f64 + 0.5) * (hi[k] - lo[k]) / counts[k] as f64
            })
        })
        .collect()
}

/// Relative error of central differences of the energy against the exact gradient, over
/// the coordinates of every third site.
fn gradient_error<const D: usize, C: hcvt_core::ConvexCell<D>>(
    boundary: &Boundary<D>,
    sites: Vec<[f64; D]>,
) -> f64
where
    Euclid: Space<D>,
    Boundary<D>: DomainKind<D>,
{
    let h = (boundary.volume() / sites.len() as f64).powf(1.0 / D as f64);
    let step = 1e-6 * h;
    let point = evaluate::<D, C, _>(boundary, sites.clone(), &PointRequest::default()).unwrap();
    let (mut err2, mut norm2) = (0.0, 0.0);
    for i in (0..sites.len()).step_by(3) {
        for k in 0..D {
            let energy_at = |delta: f64| {
                let mut moved = sites.clone();
                moved[i][k] += delta;
                evaluate::<D, C, _>(boundary, moved, &PointRequest::default())
                    .unwrap()
                    .energy
            };
            let fd = (energy_at(step) - energy_at(-step)) / (2.0 * step);
            err2 += (fd - point.gradient[i][k]).powi(2);
            norm2 += point.gradient[i][k].powi(2);
        }
    }
    (err2 / norm2).sqrt()
}

#[test]
fn gradient_matches_central_differences() {
    let l = l_shape();
    let err = gradient_error::<2, PolygonCell>(&l, interior_sites(&l, 60, 1));
    assert!(err < 1e-6, "2D: relative error {err:e}");
    let cube = cuboid([0.0, -1.0, 0.5], [2.0, 1.0, 1.5]);
    let err = gradient_error::<3, PolyhedronCell>(&cube, interior_sites(&cube, 40, 2));
    assert!(err < 1e-6, "3D: relative error {err:e}");
}

#[test]
fn hessian_matches_central_differences_of_the_gradient() {
    let l = l_shape();
    let err = hessian_error::<2, PolygonCell, _>(&l, interior_sites(&l, 60, 1));
    assert!(err < 1e-6, "2D: relative error {err:e}");
    let dented = dented_cube();
    let err = hessian_error::<3, PolyhedronCell, _>(&dented, interior_sites(&dented, 60, 2));
    assert!(err < 1e-6, "3D: relative error {err:e}");
    let without =
        evaluate::<2, PolygonCell, _>(&l, interior_sites(&l, 10, 1), &PointRequest::default())
            .unwrap();
    assert!(without.hessian_product(&[[0.0; 2]; 10]).is_none());
}

fn settings<const D: usize>(method: Method, tol: f64, max_iter: usize) -> Settings<'static, D> {
    Settings {
        method,
        rule: Rule::Gap,
        tol,
        max_iter,
        ..Settings::default()
    }
}

/// [`settings`] under the paper's rule, `‖g‖/‖X‖ < tol` in the input coordinates.
fn paper<const D: usize>(method: Method, tol: f64, max_iter: usize) -> Settings<'static, D> {
    Settings {
        rule: Rule::Paper,
        ..settings(method, tol, max_iter)
    }
}

/// The measures of `out.sites` recomputed from a fresh diagram, independent of the run's
/// history (no site is pinned in these domains' runs: checked).
fn fresh_measures<const D: usize, C: hcvt_core::ConvexCell<D>>(
    boundary: &Boundary<D>,
    out: &Outcome<D>,
) -> Measures
where
    Euclid: Space<D>,
    Boundary<D>: DomainKind<D>,
{
    assert_eq!(out.history.last().unwrap().measures.pinned, 0);
    let point = evaluate::<D, C, _>(boundary, out.sites.clone(), &PointRequest::default()).unwrap();
    Measures::of(&point, &vec![false; out.sites.len()])
}

fn run<const D: usize, C: hcvt_core::ConvexCell<D>>(
    boundary: &Boundary<D>,
    sites: Vec<[f64; D]>,
    settings: &Settings<'_, D>,
) -> hcvt_core::Outcome<D>
where
    Euclid: Space<D>,
    Boundary<D>: DomainKind<D>,
{
    cvt::<D, C, _>(boundary, sites, settings, &mut |_, _| {
        ControlFlow::Continue(())
    })
    .unwrap()
}

#[test]
fn lloyd_never_increases_the_energy() {
    let l = l_shape();
    let out = run::<2, PolygonCell>(
        &l,
        interior_sites(&l, 100, 3),
        &settings(Method::Lloyd, 0.0, 30),
    );
    assert_eq!(out.stop_reason, StopReason::MaxIter);
    assert_eq!(out.iterations(), 30);
    for pair in out.history.windows(2) {
        let (a, b) = (pair[0].energy, pair[1].energy);
        assert!(b <= a * (1.0 + 1e-13), "energy rose from {a} to {b}");
        assert_eq!(pair[1].step, Step::Lloyd);
    }
}

#[test]
fn lattices_are_fixed_points() {
    let rectangle = polygon(&[&[[-1., 2.], [5., 2.], [5., 6.], [-1., 6.]]]);
    let squares = grid([6, 4], [-1., 2.], [5., 6.]);
    let cube = cuboid([0.5, -1.0, 2.0], [2.5, 1.0, 3.5]);
    let cubes = grid([4, 4, 3], [0.5, -1.0, 2.0], [2.5, 1.0, 3.5]);
    for method in [Method::Lbfgs, Method::Lloyd, Method::Newton] {
        // tol = 0: every iteration runs, on gradients that are round-off.
        let out = run::<2, PolygonCell>(&rectangle, squares.clone(), &settings(method, 0.0, 4));
        let moved = max_move(&out.sites, &squares);
        assert!(moved < 1e-12, "{method:?}: a square moved by {moved:e}");
        let out = run::<3, PolyhedronCell>(&cube, cubes.clone(), &settings(method, 0.0, 4));
        let moved = max_move(&out.sites, &cubes);
        assert!(moved < 1e-12, "{method:?}: a cube moved by {moved:e}");
    }
}

fn max_move<const D: usize>(a: &[[f64; D]], b: &[[f64; D]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..D).map(move |k| (x[k] - y[k]).abs()))
        .fold(0.0, f64::max)
}

#[test]
fn lbfgs_converges_in_a_non_convex_polygon_and_beats_lloyd() {
    let l = l_shape();
    let sites = interior_sites(&l, 150, 4);
    let lbfgs = run::<2, PolygonCell>(&l, sites.clone(), &Settings::default());
    assert_eq!(lbfgs.stop_reason, StopReason::Converged);
    let fresh = fresh_measures::<2, PolygonCell>(&l, &lbfgs);
    assert!(fresh.rms_gap < 1e-7 && fresh.max_gap < 1e-5, "{fresh:?}");
    assert!(lbfgs
        .sites
        .iter()
        .all(|p| DomainKind::locate(&l, p) != Some(0)));
    let lloyd = run::<2, PolygonCell>(&l, sites, &settings(Method::Lloyd, 1e-4, 2000));
    assert_eq!(lloyd.stop_reason, StopReason::Converged);
    let to_1e4 = lbfgs
        .history
        .iter()
        .find(|r| r.measures.rms_gap < 1e-4)
        .unwrap();
    assert!(
        to_1e4.evaluations < lloyd.evaluations(),
        "L-BFGS {} diagrams to 1e-4, Lloyd {}",
        to_1e4.evaluations,
        lloyd.evaluations()
    );
}

#[test]
fn observer_can_stop_the_run() {
    let l = l_shape();
    let mut seen = 0;
    let out = cvt::<2, PolygonCell, _>(
        &l,
        interior_sites(&l, 30, 5),
        &Settings::default(),
        &mut |_, _| {
            seen += 1;
            if seen == 3 {
                ControlFlow::Break(())
            } else {
                ControlFlow::Continue(())
            }
        },
    )
    .unwrap();
    assert_eq!(out.stop_reason, StopReason::Interrupted);
    assert_eq!(out.iterations(), 2);
}

#[test]
fn empty_cells_are_reseeded_deterministically_inside() {
    let l = l_shape();
    let mut sites = interior_sites(&l, 20, 6);
    sites[7] = [3.5, 3.5]; // outside the L, in its missing corner: an empty cell
    let options = Options {
        allow_outside: true,
    };
    let diagram = clipped_diagram::<2, PolygonCell, _>(
        &l,
        &sites,
        &Request {
            options,
            keep_cells: false,
            ..Request::default()
        },
    )
    .map(|c| c.diagram)
    .unwrap();
    assert_eq!(diagram.moments[7].mass, 0.0);
    let point = Point {
        energy: diagram.energy(),
        gradient: diagram.gradient(),
        diagram,
        hessian: None,
        sites: sites.clone(),
    };
    let reseeded = reseed_empty(&l, &point, 0.5).unwrap();
    assert_eq!(
        reseeded,
        reseed_empty(&l, &point, 0.5).unwrap(),
        "deterministic"
    );
    assert_ne!(reseeded[7], sites[7]);
    assert_eq!(DomainKind::locate(&l, &reseeded[7]), Some(1));
    assert!((0..20).filter(|&i| i != 7).all(|i| reseeded[i] == sites[i]));
    let out = run::<2, PolygonCell>(&l, reseeded, &settings(Method::Lbfgs, 1e-6, 500));
    assert_eq!(out.stop_reason, StopReason::Converged);
    assert!(fresh_measures::<2, PolygonCell>(&l, &out).rms_gap < 1e-6);
}

#[test]
fn a_run_that_no_longer_moves_stops_as_stalled() {
    // The unit square in the plane x = 0 as a surface, 30 sites on it and one 3 off it:
    // its cell is empty, and reseeding puts it a quarter spacing along +x from the
    // largest cell's site, off the plane again, where it is as empty. Every iteration
    // then reseeds to the same sites: without a stall stop the run went to max_iter.
    let square = Surface::new(
        vec![[0., 0., 0.], [0., 1., 0.], [0., 1., 1.], [0., 0., 1.]],
        vec![[0, 1, 2], [0, 2, 3]],
    )
    .unwrap();
    let mut sites: Vec<[f64; 3]> = interior_sites(&l_shape(), 30, 8)
        .iter()
        .map(|p| [0.0, p[0] / 4.0, p[1] / 4.0])
        .collect();
    sites.push([3.0, 0.5, 0.5]);
    let out = cvt::<3, PolyhedronCell, _>(
        &square,
        sites,
        &settings(Method::Lbfgs, 1e-9, 50),
        &mut |_, _| ControlFlow::Continue(()),
    )
    .unwrap();
    assert_eq!(out.stop_reason, StopReason::Stalled);
    // The first reseed moves the site; then three idle iterations, a restart, three more.
    assert_eq!(out.iterations(), 7);
    assert!(out.history[1..].iter().all(|r| r.step == Step::Reseed));
    let energy = out.history[0].energy;
    assert!(out.history.iter().all(|r| r.energy == energy));
}

/// Newton from `sites` reaches the paper's rule with fewer diagrams than L-BFGS (both
/// reach it: checked on a fresh diagram), its sites stay in the domain and its energy
/// never rises beyond round-off.
fn newton_beats_lbfgs<const D: usize, C: hcvt_core::ConvexCell<D>>(
    boundary: &Boundary<D>,
    sites: Vec<[f64; D]>,
) where
    Euclid: Space<D>,
    Boundary<D>: DomainKind<D>,
{
    let newton = run::<D, C>(boundary, sites.clone(), &paper(Method::Newton, 1e-10, 2000));
    let lbfgs = run::<D, C>(boundary, sites, &paper(Method::Lbfgs, 1e-10, 2000));
    for out in [&newton, &lbfgs] {
        assert_eq!(out.stop_reason, StopReason::Converged, "{D}D");
        let fresh = fresh_measures::<D, C>(boundary, out);
        assert!(fresh.grad_norm < 1e-10, "{D}D: {fresh:?}");
    }
    assert!(
        newton.evaluations() < lbfgs.evaluations(),
        "{D}D: Newton {} diagrams, L-BFGS {}",
        newton.evaluations(),
        lbfgs.evaluations()
    );
    assert!(newton.history[1..].iter().all(|r| r.step == Step::Newton));
    assert!(newton
        .sites
        .iter()
        .all(|p| DomainKind::locate(boundary, p) != Some(0)));
    for pair in newton.history.windows(2) {
        assert!(pair[1].energy <= pair[0].energy * (1.0 + 1e-12), "{D}D");
    }
}

#[test]
fn newton_converges_in_non_convex_domains_with_fewer_diagrams_than_lbfgs() {
    let l = l_shape();
    newton_beats_lbfgs::<2, PolygonCell>(&l, interior_sites(&l, 150, 4));
    let dented = dented_cube();
    newton_beats_lbfgs::<3, PolyhedronCell>(&dented, interior_sites(&dented, 150, 4));
}

/// The run holds the sites along a Morton curve; the caller sees its own order: the
/// observer's first sites are the input, the outcome's diagram is the diagram of the
/// outcome's sites (same neighbours, moments to round-off, Hessian rows for Newton), and
/// an error names the first offending site in the caller's order.
#[test]
fn the_caller_sees_its_own_order() {
    let l = l_shape();
    let sites = interior_sites(&l, 200, 9);
    for method in [Method::Lbfgs, Method::Newton] {
        let mut first: Option<Vec<[f64; 2]>> = None;
        let out = cvt::<2, PolygonCell, _>(
            &l,
            sites.clone(),
            &settings(method, 1e-6, 50),
            &mut |_, s| {
                first.get_or_insert_with(|| s.to_vec());
                ControlFlow::Continue(())
            },
        )
        .unwrap();
        assert_eq!(first.as_deref(), Some(&sites[..]));
        let newton = method == Method::Newton;
        let fresh = evaluate::<2, PolygonCell, _>(
            &l,
            out.sites.clone(),
            &PointRequest {
                hessian: newton,
                density: None,
            },
        )
        .unwrap();
        let (a, b) = (&out.diagram, &fresh.diagram);
        assert_eq!(a.neighbor_offsets, b.neighbor_offsets);
        assert_eq!(a.neighbor_sites, b.neighbor_sites);
        for (ma, mb) in a.moments.iter().zip(&b.moments) {
            assert!((ma.mass - mb.mass).abs() <= 1e-12 * mb.mass);
            assert!((ma.second - mb.second).abs() <= 1e-12 * mb.second);
        }
        if method == Method::Newton {
            let v: Vec<[f64; 2]> = out.sites.iter().map(|s| [s[1].sin(), s[0].cos()]).collect();
            let (ha, hb) = (
                out.hessian.as_ref().unwrap().product(a, &v),
                fresh.hessian_product(&v).unwrap(),
            );
            let scale = hb
                .iter()
                .map(|r| r[0].abs() + r[1].abs())
                .fold(0.0, f64::max);
            for (ra, rb) in ha.iter().zip(&hb) {
                assert!((ra[0] - rb[0]).abs() + (ra[1] - rb[1]).abs() <= 1e-12 * scale);
            }
        }
    }
    let mut bad = sites.clone();
    bad[150] = [3.0, 3.0]; // outside the L
    bad[7] = [3.5, 3.5];
    let err = cvt::<2, PolygonCell, _>(&l, bad, &settings(Method::Lbfgs, 1e-6, 5), &mut |_, _| {
        ControlFlow::Continue(())
    })
    .unwrap_err();
    assert!(
        matches!(
            err,
            hcvt_core::CoreError::SiteOutsideDomain { index: 7, .. }
        ),
        "{err:?}"
    );
}

#[test]
fn fixed_sites_stay_and_the_free_ones_converge() {
    let square = polygon(&[&[[0., 0.], [1., 0.], [1., 1.], [0., 1.]]]);
    let sites = interior_sites(&square, 120, 9);
    let fixed: Vec<bool> = (0..sites.len()).map(|i| i % 5 == 0).collect();
    for method in [Method::Lbfgs, Method::Lloyd] {
        let tol = if method == Method::Lbfgs { 1e-7 } else { 1e-4 };
        let asked = Settings {
            fixed: Some(&fixed),
            ..settings(method, tol, 3000)
        };
        let out = run::<2, PolygonCell>(&square, sites.clone(), &asked);
        assert_eq!(out.stop_reason, StopReason::Converged, "{method:?}");
        for (i, (a, b)) in out.sites.iter().zip(&sites).enumerate() {
            assert_eq!(fixed[i], a == b, "site {i} ({method:?})");
        }
        // The gap over the free sites, from a fresh diagram; over all, far from it.
        let point =
            evaluate::<2, PolygonCell, _>(&square, out.sites.clone(), &PointRequest::default())
                .unwrap();
        assert!(Measures::of(&point, &fixed).rms_gap < tol);
        assert!(Measures::of(&point, &vec![false; sites.len()]).rms_gap > 100.0 * tol);
    }
    let newton = Settings {
        fixed: Some(&fixed),
        ..settings(Method::Newton, 1e-7, 100)
    };
    let refused = cvt::<2, PolygonCell, _>(&square, sites.clone(), &newton, &mut |_, _| {
        ControlFlow::Continue(())
    });
    assert!(matches!(refused, Err(CoreError::InvalidSettings { .. })));
    let short = Settings {
        fixed: Some(&fixed[1..]),
        ..settings(Method::Lbfgs, 1e-7, 100)
    };
    let refused =
        cvt::<2, PolygonCell, _>(
            &square,
            sites,
            &short,
            &mut |_, _| ControlFlow::Continue(()),
        );
    assert!(matches!(refused, Err(CoreError::ShapeMismatch { .. })));
}
