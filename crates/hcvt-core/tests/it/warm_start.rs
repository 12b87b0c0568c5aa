//! Warm-started diagrams (issue 32): a diagram started from the previous one's near-site
//! lists is the cold diagram bit for bit, on every flat domain kind, after small steps
//! (the lists certify nearly every cell) and large ones (most cells fall back to the
//! index), with any number of threads; and the warm path is really taken.

use crate::common::{data_3d, dented_cube, interior_sites, polygon, read_mesh};
use hcvt_core::lloyd::lloyd_step;
use hcvt_core::sample::Lcg;
use hcvt_core::{
    clipped_diagram, BoxDomain, ConvexCell, CoreError, Density, Diagram, DomainKind, Euclid, Field,
    PeriodicBox, PolygonCell, PolyhedronCell, Request, Space, WarmStart,
};

/// Every array of two diagrams equal bit for bit.
fn assert_same<const D: usize>(a: &Diagram<D>, b: &Diagram<D>, what: &str) {
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    let differ: Vec<usize> = (0..a.moments.len())
        .filter(|&i| a.moments[i] != b.moments[i])
        .collect();
    if !differ.is_empty() {
        let i = differ[0];
        let nb = |d: &Diagram<D>| {
            d.neighbor_sites[d.neighbor_offsets[i]..d.neighbor_offsets[i + 1]].to_vec()
        };
        panic!(
            "{what}: {} cells differ, first {i}: {:?} vs {:?}; {:?} vs {:?}",
            differ.len(),
            a.moments[i],
            b.moments[i],
            nb(a),
            nb(b)
        );
    }
    assert_eq!(a.moments, b.moments, "{what}: moments");
    assert_eq!(
        bits(&a.boundary_measure),
        bits(&b.boundary_measure),
        "{what}"
    );
    assert_eq!(a.neighbor_offsets, b.neighbor_offsets, "{what}: offsets");
    assert_eq!(a.neighbor_sites, b.neighbor_sites, "{what}: neighbours");
    assert_eq!(
        bits(&a.neighbor_measures),
        bits(&b.neighbor_measures),
        "{what}"
    );
    assert_eq!(a.neighbor_images, b.neighbor_images, "{what}: images");
    assert_eq!(a.weighted, b.weighted, "{what}: weighted");
}

/// `sites` moved by random shifts of length up to `step` (held inside `domain`).
fn moved<const D: usize, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
    step: f64,
    seed: u64,
) -> Vec<[f64; D]>
where
    Euclid: Space<D>,
{
    let mut rng = Lcg::new(seed);
    let shifts: Vec<[f64; D]> = sites
        .iter()
        .map(|_| std::array::from_fn(|_| step * (2.0 * rng.unit() - 1.0) / (D as f64).sqrt()))
        .collect();
    lloyd_step(domain, sites, &shifts)
}

/// A chain of diagrams of `sites` moved by each of `steps` (in mean spacings `h`) in
/// turn, each computed warm from the previous and cold, asserted equal; returns the
/// fraction of cells computed warm at each step, the fraction of cells rebuilt from their
/// ring (unclipped), and the last diagram.
fn warm_chain<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    mut sites: Vec<[f64; D]>,
    steps: &[f64],
    cold_request: Request<'_, D>,
    what: &str,
) -> (Vec<f64>, Vec<f64>, Diagram<D>)
where
    Euclid: Space<D>,
{
    let n = sites.len();
    let h = (domain.volume() / n as f64).powf(1.0 / D as f64);
    let mut state = WarmStart::new();
    let mut fractions = Vec::new();
    let mut rings = Vec::new();
    let mut last = Diagram::default();
    for (k, &step) in [0.0].iter().chain(steps).enumerate() {
        if k > 0 {
            sites = moved(domain, &sites, step * h, k as u64);
        }
        let warm = clipped_diagram::<D, C, K>(
            domain,
            &sites,
            &Request {
                warm: Some(&state),
                ..cold_request
            },
        )
        .unwrap();
        let cold = clipped_diagram::<D, C, K>(domain, &sites, &cold_request).unwrap();
        assert_same(&warm.diagram, &cold.diagram, &format!("{what}, step {k}"));
        if let Some(next) = warm.warm {
            state = next;
            fractions.push(state.warm_cells() as f64 / n as f64);
            rings.push(state.ring_cells() as f64 / n as f64);
        }
        last = warm.diagram;
    }
    (fractions, rings, last)
}

/// Small steps keep most cells warm; large ones send most to the index; all bitwise.
/// After a small step most cells are rebuilt from their ring, unclipped.
fn check_kind<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    what: &str,
) where
    Euclid: Space<D>,
{
    let steps = [0.01, 0.01, 0.02, 0.15, 1.0, 0.01, 0.01];
    let (fractions, rings, _) =
        warm_chain::<D, C, K>(domain, sites, &steps, Request::default(), what);
    assert_eq!(fractions[0], 0.0, "{what}: the first diagram is cold");
    // Random sites: about 60% in 2D and 37-40% in 3D; a CVT's cells, more regular, more
    // (benchmarks/warm_start.py).
    let least = if D == 2 { 0.5 } else { 0.3 };
    assert!(
        rings[1] > least && rings[2] > least,
        "{what}: rings {rings:?}"
    );
    assert!(rings[4] < rings[2], "{what}: rings {rings:?}");
    assert_eq!(rings[5..7], [0.0, 0.0], "{what}: a large step");
    assert!(fractions[1] > 0.9, "{what}: small steps {fractions:?}");
    assert!(fractions[2] > 0.9, "{what}: small steps {fractions:?}");
    // A step of 0.15 spacings: some cells fall back to the index, most stay warm.
    assert!(
        fractions[4] < 1.0 && fractions[4] > 0.5,
        "{what}: {fractions:?}"
    );
    // A step of a spacing: the diagram goes cold and records nothing; the next records
    // afresh, cold, and the one after is warm again.
    assert_eq!(fractions[5..7], [0.0, 0.0], "{what}: a large step");
    assert!(
        fractions[7] > 0.9,
        "{what}: small steps again {fractions:?}"
    );
}

#[test]
fn a_warm_polygon_diagram_is_the_cold_one() {
    let holed = polygon(&[
        &[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        &[[0.3, 0.3], [0.3, 0.6], [0.6, 0.6], [0.6, 0.3]],
    ]);
    check_kind::<2, PolygonCell, _>(&holed, interior_sites(&holed, 3000, 3), "holed square");
}

#[test]
fn a_warm_solid_diagram_is_the_cold_one() {
    let dented = dented_cube();
    check_kind::<3, PolyhedronCell, _>(&dented, interior_sites(&dented, 1500, 5), "dented cube");
    if let Some(dir) = data_3d() {
        let bunny = read_mesh(&dir.join("bunny.off"));
        check_kind::<3, PolyhedronCell, _>(&bunny, interior_sites(&bunny, 1500, 6), "bunny");
    }
}

#[test]
fn a_warm_box_diagram_is_the_cold_one() {
    let square = BoxDomain::new([0.0, -1.0], [2.0, 1.0]).unwrap();
    check_kind::<2, PolygonCell, _>(&square, interior_sites(&square, 2000, 7), "2D box");
    let cube = BoxDomain::new([0.0; 3], [1.0, 2.0, 1.0]).unwrap();
    check_kind::<3, PolyhedronCell, _>(&cube, interior_sites(&cube, 1500, 8), "3D box");
}

/// One site's long move among small ones (a Newton step across a rearranging cell) leaves
/// the cells away from it warm: a list loses its certificate only where a long mover can
/// have come near. Bitwise the cold diagram. `centre`: a point well inside `domain`.
fn check_one_long_move<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: Vec<[f64; D]>,
    centre: [f64; D],
    what: &str,
) where
    Euclid: Space<D>,
{
    let n = sites.len();
    let h = (domain.volume() / n as f64).powf(1.0 / D as f64);
    let recording = Request {
        warm: Some(&WarmStart::new()),
        ..Request::default()
    };
    let first = clipped_diagram::<D, C, K>(domain, &sites, &recording).unwrap();
    let state = first.warm.expect("the lists recorded");
    let mut next = moved(domain, &sites, 0.005 * h, 1);
    let distance = |s: &[f64; D]| (0..D).map(|k| (s[k] - centre[k]).powi(2)).sum::<f64>();
    let long = (0..n)
        .min_by(|&a, &b| distance(&sites[a]).total_cmp(&distance(&sites[b])))
        .unwrap();
    next[long][0] += 0.4 * h;
    let request = Request {
        warm: Some(&state),
        ..Request::default()
    };
    let warm = clipped_diagram::<D, C, K>(domain, &next, &request).unwrap();
    let cold = clipped_diagram::<D, C, K>(domain, &next, &Request::default()).unwrap();
    assert_same(&warm.diagram, &cold.diagram, what);
    let warm_cells = warm.warm.expect("the lists recorded").warm_cells();
    assert!(
        warm_cells as f64 > 0.9 * n as f64,
        "{what}: {warm_cells} of {n} cells warm"
    );
}

#[test]
fn one_long_move_leaves_the_other_cells_warm() {
    let square = polygon(&[&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]]);
    let sites = interior_sites(&square, 2000, 12);
    check_one_long_move::<2, PolygonCell, _>(&square, sites, [0.5, 0.5], "square");
    let dented = dented_cube();
    let sites = interior_sites(&dented, 1500, 13);
    check_one_long_move::<3, PolyhedronCell, _>(&dented, sites, [0.5, 0.5, 0.4], "dented cube");
}

/// A power diagram streams its sites the same way: warm is cold there too.
#[test]
fn a_warm_power_diagram_is_the_cold_one() {
    let square = polygon(&[&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]]);
    let sites = interior_sites(&square, 2000, 9);
    let mut rng = Lcg::new(4);
    let h2 = 1.0 / sites.len() as f64;
    let weights: Vec<f64> = sites.iter().map(|_| 0.3 * h2 * rng.unit()).collect();
    let (fractions, _, _) = warm_chain::<2, PolygonCell, _>(
        &square,
        sites,
        &[0.01, 0.01, 0.15],
        Request {
            weights: Some(&weights),
            ..Request::default()
        },
        "power",
    );
    assert!(fractions[1] > 0.9, "{fractions:?}");
    assert!(fractions[3] < 1.0, "{fractions:?}");
}

/// A field for the sampled density: `1 + x² + exp(y)`, one value per node.
struct Bumpy;

impl Field<2> for Bumpy {
    fn values(&self, points: Vec<[f64; 2]>) -> Result<Vec<f64>, CoreError> {
        Ok(points
            .iter()
            .map(|p| 1.0 + p[0] * p[0] + p[1].exp())
            .collect())
    }
}

/// A sampled density visits the sites in the cold (Morton) order, not the recording
/// diagram's: each cell finds its list by its site, and the cells are the cold ones.
#[test]
fn a_warm_diagram_with_a_sampled_density_is_the_cold_one() {
    let square = polygon(&[&[[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]]]);
    let sites = interior_sites(&square, 2000, 12);
    let field = Bumpy;
    let density = Density::Sampled {
        field: &field,
        degree: 2,
    };
    let request = Request {
        density: Some(&density),
        ..Request::default()
    };
    let (fractions, _, _) =
        warm_chain::<2, PolygonCell, _>(&square, sites, &[0.01, 0.15, 0.01], request, "sampled");
    assert!(fractions[1] > 0.9, "{fractions:?}");
    assert!(fractions[2] < 1.0, "{fractions:?}");
}

/// A periodic box computes its cells among images: it ignores the warm start (and
/// returns none), bitwise the cold diagram.
#[test]
fn a_periodic_box_ignores_the_warm_start() {
    let torus = PeriodicBox::new([0.0; 2], [1.0; 2], [true, false]).unwrap();
    let sites = interior_sites(&torus, 800, 10);
    let (fractions, _, _) = warm_chain::<2, PolygonCell, _>(
        &torus,
        sites,
        &[0.01, 1.0],
        Request::default(),
        "periodic",
    );
    assert!(fractions.is_empty());
}

/// The same warm chain with 1 and 3 threads: the same diagrams and the same warm cells.
#[test]
fn a_warm_chain_is_the_same_with_one_or_three_threads() {
    let dented = dented_cube();
    let sites = interior_sites(&dented, 1200, 11);
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| {
            warm_chain::<3, PolyhedronCell, _>(
                &dented,
                sites.clone(),
                &[0.01, 0.3],
                Request::default(),
                "threads",
            )
        })
    };
    let (one, _, a) = run(1);
    let (three, _, b) = run(3);
    assert_eq!(one, three);
    assert_same(&a, &b, "1 against 3 threads");
}
