//! Profile cold or warm-started diagrams of one late CVT iterate (issue 32), under `perf`.
//!
//! `warm_profile DIM MESH SITES make ITERATIONS FILE`: writes the iterate of an L-BFGS CVT of
//! `ITERATIONS` steps from random interior sites to `FILE` (one site a line).
//! `warm_profile DIM MESH SITES (cold|warm) REPEATS FILE`: reads it, takes one Lloyd step,
//! and computes that step's diagram `REPEATS` times, cold or warm-started from the
//! iterate's own near-site lists; prints the median time per diagram. `MESH_v.txt` and
//! `MESH_f.txt` are as `warm_start` reads them (`benchmarks/warm_start.py` writes them).

#[path = "common/rows.rs"]
mod rows;

use std::io::Write;
use std::ops::ControlFlow;
use std::time::Instant;

use hcvt_core::lloyd::lloyd_sites;
use hcvt_core::sample::interior_sites;
use hcvt_core::{
    cvt, evaluate, evaluate_warm, ConvexCell, CoreError, DomainKind, Euclid, Method, PointRequest,
    Polygon, PolygonCell, PolyhedronCell, Settings, Solid, Space, WarmStart,
};
use rows::read_rows;

fn run<const D: usize, C: ConvexCell<D>, K: DomainKind<D>>(
    domain: &K,
    n: usize,
    mode: &str,
    count: usize,
    file: &str,
) -> Result<(), CoreError>
where
    Euclid: Space<D>,
{
    if mode == "make" {
        let settings = Settings {
            method: Method::Lbfgs,
            max_iter: count,
            tol: 0.0,
            ..Settings::default()
        };
        let late = cvt::<D, C, K>(
            domain,
            interior_sites(domain, n, 7),
            &settings,
            &mut |_, _| ControlFlow::Continue(()),
        )?;
        let mut out = std::fs::File::create(file).expect("sites file");
        for s in &late.sites {
            let row: Vec<String> = s.iter().map(|x| format!("{x:?}")).collect();
            writeln!(out, "{}", row.join(" ")).expect("write");
        }
        return Ok(());
    }
    let late: Vec<[f64; D]> = read_rows(file);
    let request = PointRequest::default();
    let mut state = WarmStart::new();
    let first = evaluate_warm::<D, C, K>(domain, late, &request, &mut state)?;
    let next = lloyd_sites(domain, &first);
    let mut ms = Vec::new();
    let mut checksum = 0.0;
    for _ in 0..count {
        // The state is cloned outside the timing: each diagram starts from the iterate's.
        let mut warm = state.clone();
        let t = Instant::now();
        let point = if mode == "warm" {
            evaluate_warm::<D, C, K>(domain, next.clone(), &request, &mut warm)?
        } else {
            evaluate::<D, C, K>(domain, next.clone(), &request)?
        };
        ms.push(1e3 * t.elapsed().as_secs_f64());
        checksum += point.energy;
    }
    ms.sort_by(f64::total_cmp);
    println!(
        "{mode}: median {:.3} ms over {count} diagrams (energy sum {checksum:e})",
        ms[ms.len() / 2]
    );
    Ok(())
}

fn main() -> Result<(), CoreError> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let usage = "usage: warm_profile DIM MESH SITES (make|cold|warm) COUNT FILE";
    let dim: usize = args.first().and_then(|a| a.parse().ok()).expect(usage);
    let mesh = args.get(1).expect(usage);
    let n: usize = args.get(2).and_then(|a| a.parse().ok()).expect(usage);
    let mode = args.get(3).expect(usage).as_str();
    let count: usize = args.get(4).and_then(|a| a.parse().ok()).expect(usage);
    let file = args.get(5).expect(usage);
    if dim == 2 {
        let vertices: Vec<[f64; 2]> = read_rows(&format!("{mesh}_v.txt"));
        let edges: Vec<[u32; 2]> = read_rows(&format!("{mesh}_f.txt"));
        let domain = Polygon::new(vertices, edges)?;
        run::<2, PolygonCell, _>(&domain, n, mode, count, file)
    } else {
        let vertices: Vec<[f64; 3]> = read_rows(&format!("{mesh}_v.txt"));
        let faces: Vec<[u32; 3]> = read_rows(&format!("{mesh}_f.txt"));
        let domain = Solid::new(vertices, faces)?;
        run::<3, PolyhedronCell, _>(&domain, n, mode, count, file)
    }
}
