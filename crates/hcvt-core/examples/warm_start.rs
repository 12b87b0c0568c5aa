//! Cold against warm-started diagrams at a late CVT iterate (issue 32), run by
//! `benchmarks/warm_start.py`.
//!
//! `warm_start DIM MESH SITES [iterations] [steps] [repeats]`: `MESH_v.txt` holds the
//! vertices (`x y` or `x y z` a line), `MESH_f.txt` the boundary (edges `a b` in 2D,
//! triangles `a b c` in 3D), `SITES` is the number of random interior sites. An L-BFGS CVT
//! of `iterations` steps (default 100; warm-started, as every CVT now is) gives the late
//! iterate; from it `steps` Lloyd steps (default 6) are taken twice, once with cold
//! diagrams and once warm-started, `repeats` times (default 3). Prints one line per
//! diagram timing and checks the two chains bitwise equal (exits non-zero otherwise).

#[path = "common/rows.rs"]
mod rows;

use std::ops::ControlFlow;
use std::time::Instant;

use hcvt_core::lloyd::lloyd_sites;
use hcvt_core::sample::interior_sites;
use hcvt_core::{
    cvt, evaluate, evaluate_warm, ConvexCell, CoreError, DomainKind, Euclid, Method, Point,
    PointRequest, Polygon, PolygonCell, PolyhedronCell, Settings, Solid, Space, WarmStart,
};
use rows::read_rows;

/// Median of `values` (sorted in place).
fn median(values: &mut [f64]) -> f64 {
    values.sort_by(f64::total_cmp);
    values[values.len() / 2]
}

/// Whether two points' diagrams agree bit for bit (moments, faces and their measures).
fn same<const D: usize>(a: &Point<D>, b: &Point<D>) -> bool {
    a.diagram.moments == b.diagram.moments
        && a.diagram.neighbor_offsets == b.diagram.neighbor_offsets
        && a.diagram.neighbor_sites == b.diagram.neighbor_sites
        && (a.diagram.neighbor_measures.iter())
            .zip(&b.diagram.neighbor_measures)
            .all(|(x, y)| x.to_bits() == y.to_bits())
        && a.energy.to_bits() == b.energy.to_bits()
}

/// Bytes per site of a warm start recorded by a cold diagram of `sites`.
fn late_bytes<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    sites: &[[f64; D]],
) -> Result<usize, CoreError>
where
    Euclid: Space<D>,
{
    let mut state = WarmStart::new();
    evaluate_warm::<D, C, K>(domain, sites.to_vec(), &PointRequest::default(), &mut state)?;
    Ok(state.bytes() / sites.len())
}

fn run<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    n: usize,
    iterations: usize,
    steps: usize,
    repeats: usize,
) -> Result<bool, CoreError>
where
    Euclid: Space<D>,
{
    let settings = Settings {
        method: Method::Lbfgs,
        max_iter: iterations,
        tol: 0.0,
        ..Settings::default()
    };
    let t = Instant::now();
    let late = cvt::<D, C, K>(
        domain,
        interior_sites(domain, n, 7),
        &settings,
        &mut |_, _| ControlFlow::Continue(()),
    )?;
    println!(
        "late iterate: {n} sites, {} L-BFGS iterations, {} diagrams, {:.2} s",
        late.iterations(),
        late.evaluations(),
        t.elapsed().as_secs_f64()
    );
    let request = PointRequest::default();
    let (mut cold_ms, mut warm_ms) = (Vec::new(), Vec::new());
    let mut equal = true;
    let (mut warm_cells, mut ring_cells) = (0, 0);
    for _ in 0..repeats {
        let mut cold = evaluate::<D, C, K>(domain, late.sites.clone(), &request)?;
        let mut state = WarmStart::new();
        let mut warm = evaluate_warm::<D, C, K>(domain, late.sites.clone(), &request, &mut state)?;
        for _ in 0..steps {
            let next = lloyd_sites(domain, &cold);
            let t = Instant::now();
            cold = evaluate::<D, C, K>(domain, next, &request)?;
            cold_ms.push(1e3 * t.elapsed().as_secs_f64());
            let next = lloyd_sites(domain, &warm);
            let t = Instant::now();
            warm = evaluate_warm::<D, C, K>(domain, next, &request, &mut state)?;
            warm_ms.push(1e3 * t.elapsed().as_secs_f64());
            warm_cells += state.warm_cells();
            ring_cells += state.ring_cells();
            equal &= same(&cold, &warm);
        }
    }
    let (c, w) = (median(&mut cold_ms), median(&mut warm_ms));
    println!(
        "per diagram (median of {} Lloyd steps): cold {c:.3} ms, warm {w:.3} ms, warm/cold {:.3}, \
         cells warm {:.1}% (rebuilt from their ring {:.1}%), near-site lists {} B/site, \
         bitwise equal: {equal}",
        cold_ms.len(),
        w / c,
        100.0 * warm_cells as f64 / (n * cold_ms.len()) as f64,
        100.0 * ring_cells as f64 / (n * cold_ms.len()) as f64,
        late_bytes::<D, C, K>(domain, &late.sites)?,
    );
    Ok(equal)
}

fn main() -> Result<(), CoreError> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: warm_start DIM MESH SITES [iterations] [steps] [repeats]";
    let dim: usize = args.first().and_then(|a| a.parse().ok()).expect(usage);
    let mesh = args.get(1).expect(usage);
    let n: usize = args.get(2).and_then(|a| a.parse().ok()).expect(usage);
    let count =
        |k: usize, default: usize| args.get(k).and_then(|a| a.parse().ok()).unwrap_or(default);
    let (iterations, steps, repeats) = (count(3, 100), count(4, 6), count(5, 3));
    let equal = if dim == 2 {
        let vertices: Vec<[f64; 2]> = read_rows(&format!("{mesh}_v.txt"));
        let edges: Vec<[u32; 2]> = read_rows(&format!("{mesh}_f.txt"));
        let domain = Polygon::new(vertices, edges)?;
        run::<2, PolygonCell, _>(&domain, n, iterations, steps, repeats)?
    } else {
        let vertices: Vec<[f64; 3]> = read_rows(&format!("{mesh}_v.txt"));
        let faces: Vec<[u32; 3]> = read_rows(&format!("{mesh}_f.txt"));
        let domain = Solid::new(vertices, faces)?;
        run::<3, PolyhedronCell, _>(&domain, n, iterations, steps, repeats)?
    };
    if !equal {
        eprintln!("warm and cold diagrams differ");
        std::process::exit(1);
    }
    Ok(())
}
