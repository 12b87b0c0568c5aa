//! Power diagrams and prescribed masses (DESIGN §14): the damped Newton iteration of
//! `optimal_transport` reaches every target mass to 1e-10 relative in a polygon, a
//! periodic box and a 3D box, with a polynomial density too; its power diagram, computed
//! again from the weights, has those masses; the weights do not depend on the thread count;
//! masses that cannot be met are refused by name.

use hcvt_core::sample::{interior_sites, Lcg};
use hcvt_core::{
    clipped_diagram, optimal_transport, optimal_transport_from, BoxDomain, ConvexCell, CoreError,
    Density, DomainKind, Euclid, PeriodicBox, Polygon, PolygonCell, PolyhedronCell, Quadratic,
    Request, Space, Transport, TransportSettings,
};

fn settings<const D: usize>() -> TransportSettings<'static, D> {
    TransportSettings {
        tol: 1e-10,
        max_iter: 50,
        density: None,
        normalise: false,
    }
}

/// The L-shape of area 3: [0, 2]² without [1, 2]².
fn l_shape() -> Polygon {
    Polygon::from_rings(&[&[
        [0.0, 0.0],
        [2.0, 0.0],
        [2.0, 1.0],
        [1.0, 1.0],
        [1.0, 2.0],
        [0.0, 2.0],
    ]])
    .unwrap()
}

/// Masses between 0.5 and 1.5 times the mean, summing to `total`.
fn random_masses(n: usize, total: f64, seed: u64) -> Vec<f64> {
    let mut rng = Lcg::new(seed);
    let raw: Vec<f64> = (0..n).map(|_| 0.5 + rng.unit()).collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|m| m * total / sum).collect()
}

/// The run converged, and the power diagram of its weights, computed afresh, has the
/// target masses to `tol`.
fn check<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    out: &Transport<D>,
    density: Option<&Density<'_, D>>,
) where
    Euclid: Space<D>,
{
    assert!(out.converged, "max error {:e}", out.max_error);
    let again = clipped_diagram::<D, C, K>(
        domain,
        sites,
        &Request {
            weights: Some(&out.weights),
            density,
            ..Request::default()
        },
    )
    .unwrap()
    .diagram;
    for (i, (m, t)) in again.masses().iter().zip(&out.targets).enumerate() {
        assert!((m - t).abs() <= 1e-10 * t, "cell {i}: {m} against {t}");
    }
    // Damped Newton converges locally quadratically: the last steps are full ones.
    assert_eq!(out.history.last().unwrap().step, 1.0);
}

#[test]
fn masses_in_an_l_shape_are_met() {
    let l_shape = l_shape();
    let sites = interior_sites(&l_shape, 2000, 3);
    let masses = random_masses(sites.len(), 3.0, 4);
    let out =
        optimal_transport::<2, PolygonCell, _>(&l_shape, &sites, &masses, &settings()).unwrap();
    check::<2, PolygonCell, _>(&l_shape, &sites, &out, None);
    assert!(
        out.history.len() <= 15,
        "{} Newton steps",
        out.history.len()
    );
}

#[test]
fn masses_with_a_polynomial_density_are_met() {
    let square = BoxDomain::new([0.0, 0.0], [1.0, 1.0]).unwrap();
    let sites = interior_sites(&square, 1000, 5);
    // ρ = 1 + 2x + y²: ∫ρ over the unit square is 1 + 1 + 1/3.
    let density =
        Density::Polynomial(Quadratic::new(1.0, [2.0, 0.0], [[0.0, 0.0], [0.0, 1.0]]).unwrap());
    let masses = random_masses(sites.len(), 7.0 / 3.0, 6);
    let out = optimal_transport::<2, PolygonCell, _>(
        &square,
        &sites,
        &masses,
        &TransportSettings {
            density: Some(&density),
            ..settings()
        },
    )
    .unwrap();
    check::<2, PolygonCell, _>(&square, &sites, &out, Some(&density));
}

/// With a polynomial the trial diagrams sum the cells' masses alone: the returned diagram
/// holds every weighted moment all the same, those of the power diagram of its weights
/// computed afresh, whether the run ends where it was expected to, at `max_iter`, with no
/// step at all, or from a warm start that is the answer already; in 2D and 3D.
#[test]
fn a_polynomials_returned_diagram_has_its_weighted_moments_however_the_run_ends() {
    let square = BoxDomain::new([0.0, 0.0], [1.0, 1.0]).unwrap();
    let sites = interior_sites(&square, 800, 8);
    let density =
        Density::Polynomial(Quadratic::new(1.0, [1.0, 0.0], [[0.0, 0.0], [0.0, 2.0]]).unwrap());
    let masses = vec![(1.0 + 0.5 + 2.0 / 3.0) / sites.len() as f64; sites.len()];
    returned_moments::<2, PolygonCell, _>(&square, &sites, &masses, &density);
    let cube = BoxDomain::new([0.0; 3], [1.0; 3]).unwrap();
    let sites = interior_sites(&cube, 300, 9);
    let density = Density::Polynomial(
        Quadratic::new(
            1.0,
            [0.5, 0.0, 1.0],
            [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]],
        )
        .unwrap(),
    );
    let masses = vec![(1.0 + 0.75 + 1.0 / 3.0) / sites.len() as f64; sites.len()];
    returned_moments::<3, PolyhedronCell, _>(&cube, &sites, &masses, &density);
}

fn returned_moments<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    masses: &[f64],
    density: &Density<'_, D>,
) where
    Euclid: Space<D>,
{
    let run = |max_iter: usize, start: Option<&[f64]>| {
        let settings = TransportSettings {
            density: Some(density),
            max_iter,
            ..settings()
        };
        optimal_transport_from::<D, C, K>(domain, sites, masses, start, &settings).unwrap()
    };
    let solved = run(50, None);
    assert!(solved.converged, "max error {:e}", solved.max_error);
    let cut_short = run(2, None);
    assert!(!cut_short.converged && cut_short.history.len() == 2);
    let warm = run(50, Some(&solved.weights));
    assert!(warm.converged && warm.history.is_empty());
    for out in [solved, cut_short, run(0, None), warm] {
        let again = clipped_diagram::<D, C, K>(
            domain,
            sites,
            &Request {
                weights: Some(&out.weights),
                density: Some(density),
                ..Request::default()
            },
        )
        .unwrap()
        .diagram;
        let pairs = out.diagram.weighted.iter().zip(&again.weighted);
        for (i, (m, a)) in pairs.enumerate() {
            let scale = a.mass.abs() + a.second.abs();
            let near = |x: f64, y: f64| (x - y).abs() <= 1e-12 * scale;
            assert!(
                near(m.mass, a.mass) && near(m.second, a.second),
                "cell {i}: {m:?} {a:?}"
            );
            assert!(m.second > 0.0, "cell {i}: {m:?}");
            for k in 0..D {
                assert!(near(m.first[k], a.first[k]), "cell {i}: {m:?} {a:?}");
            }
        }
        assert_eq!(out.diagram.weighted.len(), sites.len());
    }
}

#[test]
fn masses_in_a_periodic_box_and_a_3d_box_are_met() {
    let torus = PeriodicBox::new([0.0, 0.0], [1.0, 2.0], [true, true]).unwrap();
    let sites = interior_sites(&torus, 800, 7);
    let masses = random_masses(sites.len(), 2.0, 8);
    let out = optimal_transport::<2, PolygonCell, _>(&torus, &sites, &masses, &settings()).unwrap();
    check::<2, PolygonCell, _>(&torus, &sites, &out, None);

    let cube = BoxDomain::new([0.0; 3], [1.0; 3]).unwrap();
    let sites = interior_sites(&cube, 1000, 9);
    let masses = random_masses(sites.len(), 1.0, 10);
    let out =
        optimal_transport::<3, PolyhedronCell, _>(&cube, &sites, &masses, &settings()).unwrap();
    check::<3, PolyhedronCell, _>(&cube, &sites, &out, None);
}

/// The weights do not depend on the thread count, nor on the stored margins of the trial
/// diagrams (`Power::hinted_cell`: cells certified by a margin taken at an earlier iterate
/// instead of their scan): bit for bit on 1 and 3 threads with margins, 1 without, in a
/// square and an L-shape (whose notch's cells meet sites outside the domain), and a cube.
#[test]
fn weights_do_not_depend_on_the_thread_count_nor_the_stored_margins() {
    let square = Polygon::from_rings(&[&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]]).unwrap();
    let l_shape = l_shape();
    for (domain, n, area, masses_seed) in [(&square, 5000, 1.0, 12), (&l_shape, 3000, 3.0, 14)] {
        let sites = interior_sites(domain, n, 11);
        let masses = random_masses(sites.len(), area, masses_seed);
        same_bits_with_and_without_margins::<2, PolygonCell, _>(domain, &sites, &masses);
    }
    let cube = BoxDomain::new([0.0; 3], [1.0; 3]).unwrap();
    let sites = interior_sites(&cube, 1000, 9);
    let masses = random_masses(sites.len(), 1.0, 10);
    same_bits_with_and_without_margins::<3, PolyhedronCell, _>(&cube, &sites, &masses);
}

/// The transport on 1 and 3 threads with stored margins and on 1 without: the weights and
/// the history bit for bit, and the margins certified more than half a diagram's cells.
fn same_bits_with_and_without_margins<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    masses: &[f64],
) where
    Euclid: Space<D>,
{
    let run = |threads: usize, margins: bool| {
        hcvt_core::set_stored_margins(margins);
        let out = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| optimal_transport::<D, C, K>(domain, sites, masses, &settings()).unwrap());
        hcvt_core::set_stored_margins(true);
        out
    };
    let (one, three, without) = (run(1, true), run(3, true), run(1, false));
    let certified =
        |out: &Transport<D>| -> usize { out.history.iter().map(|r| r.margin_cells).sum() };
    // The margins certified cells (most of the last diagrams'), and only when on.
    assert!(
        certified(&one) > sites.len() / 2,
        "{} cells",
        certified(&one)
    );
    assert_eq!(certified(&without), 0);
    let steps = |out: &Transport<D>| -> Vec<_> {
        (out.history.iter())
            .map(|r| {
                (
                    r.max_error.to_bits(),
                    r.step.to_bits(),
                    r.cg_iterations,
                    r.diagrams,
                )
            })
            .collect()
    };
    for other in [&three, &without] {
        assert!(one
            .weights
            .iter()
            .map(|w| w.to_bits())
            .eq(other.weights.iter().map(|w| w.to_bits())));
        assert_eq!(steps(&one), steps(other));
    }
    assert_eq!(one.history, three.history);
}

/// The step lengths tried: from zero weights the first step tries 1/2, every later one 1,
/// halving from there; from given weights the first step tries 1. Checked through the
/// diagrams each step computed: `t₀ / t = 2^(k−1)` for `k` diagrams and the step `t` taken.
#[test]
fn newton_steps_try_half_a_step_first_from_zero_weights_and_full_ones_after() {
    let square = BoxDomain::new([0.0, 0.0], [1.0, 1.0]).unwrap();
    let sites = interior_sites(&square, 3000, 21);
    let masses = random_masses(sites.len(), 1.0, 22);
    let out =
        optimal_transport::<2, PolygonCell, _>(&square, &sites, &masses, &settings()).unwrap();
    check::<2, PolygonCell, _>(&square, &sites, &out, None);
    let mut first = 0.5;
    for (k, r) in out.history.iter().enumerate() {
        let halvings = (first / r.step).log2();
        assert_eq!(halvings, halvings.round(), "step {k}: {r:?}");
        assert_eq!(r.diagrams, 1 + halvings as usize, "step {k}: {r:?}");
        first = 1.0;
    }
    // From the weights of the solution, masses 0.1% off: the full step first, and taken.
    let nearby: Vec<f64> = masses
        .iter()
        .enumerate()
        .map(|(i, m)| m * if i % 2 == 0 { 1.001 } else { 0.999 })
        .collect();
    let total: f64 = nearby.iter().sum();
    let nearby: Vec<f64> = nearby.iter().map(|m| m / total).collect();
    let warm = optimal_transport_from::<2, PolygonCell, _>(
        &square,
        &sites,
        &nearby,
        Some(&out.weights),
        &settings(),
    )
    .unwrap();
    check::<2, PolygonCell, _>(&square, &sites, &warm, None);
    assert_eq!((warm.history[0].step, warm.history[0].diagrams), (1.0, 1));
}

#[test]
fn masses_that_cannot_be_met_are_refused() {
    let square = BoxDomain::new([0.0, 0.0], [1.0, 1.0]).unwrap();
    let sites = interior_sites(&square, 10, 13);
    let run = |masses: &[f64], normalise: bool| {
        optimal_transport::<2, PolygonCell, _>(
            &square,
            &sites,
            masses,
            &TransportSettings {
                normalise,
                ..settings()
            },
        )
    };
    let bad = |r: Result<Transport<2>, CoreError>, what: &str| match r {
        Err(CoreError::InvalidWeights { reason }) => assert!(reason.contains(what), "{reason}"),
        other => panic!("{:?}", other.map(|t| t.max_error)),
    };
    bad(run(&[0.1; 9], false), "one per site");
    bad(run(&[0.2; 10], false), "sum to");
    let mut negative = [0.1; 10];
    negative[4] = -0.1;
    bad(run(&negative, false), "mass 4");
    // Relative masses, normalised to the domain's mass.
    let out = run(&[2.0; 10], true).unwrap();
    assert!(out.converged);
    assert!(out.targets.iter().all(|t| (t - 0.1).abs() < 1e-15));
}

/// The power diagram of `weights` started from `start`'s neighbours
/// (`Request::power_start`) against the one streamed cold: every cell's mass to 1e-12 of
/// the domain's mean cell, and the same neighbours across every face of measure above
/// round-off.
fn started_matches_cold<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    weights: &[f64],
    start: &hcvt_core::Diagram<D>,
) where
    Euclid: Space<D>,
{
    let request = Request {
        weights: Some(weights),
        ..Request::default()
    };
    let cold = clipped_diagram::<D, C, K>(domain, sites, &request)
        .unwrap()
        .diagram;
    let started = clipped_diagram::<D, C, K>(
        domain,
        sites,
        &Request {
            power_start: Some(start),
            ..request
        },
    )
    .unwrap()
    .diagram;
    let mean = cold.masses().iter().sum::<f64>() / sites.len() as f64;
    let faces = |d: &hcvt_core::Diagram<D>, i: usize| {
        let mut f: Vec<u32> = (d.neighbor_offsets[i]..d.neighbor_offsets[i + 1])
            .filter(|&e| d.neighbor_measures[e] > 1e-9 * mean)
            .map(|e| d.neighbor_sites[e])
            .collect();
        f.sort_unstable();
        f
    };
    for (i, (a, b)) in cold.masses().iter().zip(started.masses()).enumerate() {
        assert!((a - b).abs() <= 1e-12 * mean, "cell {i}: {a} against {b}");
        assert_eq!(faces(&cold, i), faces(&started, i), "cell {i}");
    }
}

/// A cell started from another diagram's neighbours is certified exact whatever they were:
/// the Voronoi diagram's, the previous Newton step's, or a diagram of unrelated weights
/// (2D in the L-shape, whose cells at the notch fall back to the stream, and 3D).
#[test]
fn a_power_start_gives_the_cold_cells_whatever_it_was() {
    let l_shape = l_shape();
    let sites = interior_sites(&l_shape, 600, 13);
    let masses = random_masses(sites.len(), 3.0, 14);
    let out =
        optimal_transport::<2, PolygonCell, _>(&l_shape, &sites, &masses, &settings()).unwrap();
    let diagram_of = |weights: Option<&[f64]>| {
        let request = Request {
            weights,
            ..Request::default()
        };
        clipped_diagram::<2, PolygonCell, _>(&l_shape, &sites, &request)
            .unwrap()
            .diagram
    };
    let mut rng = Lcg::new(15);
    let unrelated: Vec<f64> = (0..sites.len()).map(|_| 0.01 * rng.unit()).collect();
    for start in [
        diagram_of(None),
        out.diagram.clone(),
        diagram_of(Some(&unrelated)),
    ] {
        started_matches_cold::<2, PolygonCell, _>(&l_shape, &sites, &out.weights, &start);
        started_matches_cold::<2, PolygonCell, _>(&l_shape, &sites, &unrelated, &start);
    }

    let cube = BoxDomain::new([0.0; 3], [1.0; 3]).unwrap();
    let sites = interior_sites(&cube, 400, 16);
    let masses = random_masses(sites.len(), 1.0, 17);
    let out =
        optimal_transport::<3, PolyhedronCell, _>(&cube, &sites, &masses, &settings()).unwrap();
    let voronoi = clipped_diagram::<3, PolyhedronCell, _>(&cube, &sites, &Request::default())
        .unwrap()
        .diagram;
    started_matches_cold::<3, PolyhedronCell, _>(&cube, &sites, &out.weights, &voronoi);
}
