//! Time the diagram of uniform random sites in the unit square or cube, periodic and not.
//! `cargo run --release --example periodic_profile -- 2 100000 [repeats] [periodic|box]`

use std::time::Instant;

use hcvt_core::sample::Lcg;
use hcvt_core::{
    clipped_diagram, BoxDomain, ConvexCell, DomainKind, Euclid, PeriodicBox, PolygonCell,
    PolyhedronCell, Request, Space,
};

fn run<const D: usize, C: ConvexCell<D>>(
    n: usize,
    repeats: usize,
    only: Option<String>,
) -> Result<(), hcvt_core::CoreError>
where
    Euclid: Space<D>,
{
    let mut rng = Lcg::new(7);
    let sites: Vec<[f64; D]> = (0..n)
        .map(|_| std::array::from_fn(|_| rng.unit()))
        .collect();
    let torus = PeriodicBox::new([0.0; D], [1.0; D], [true; D])?;
    let plain = BoxDomain::new([0.0; D], [1.0; D])?;
    if let Some(kind) = only {
        // One kind alone, for an instruction count (valgrind --tool=cachegrind).
        let d = if kind == "box" {
            clipped_diagram::<D, C, _>(&plain, &sites, &Request::default())?.diagram
        } else {
            clipped_diagram::<D, C, _>(&torus, &sites, &Request::default())?.diagram
        };
        println!("{kind}: {} faces", d.neighbor_sites.len());
        return Ok(());
    }
    for _ in 0..repeats {
        let t = Instant::now();
        let d = clipped_diagram::<D, C, _>(&torus, &sites, &Request::default())?.diagram;
        let periodic = t.elapsed().as_secs_f64();
        let t = Instant::now();
        let b = clipped_diagram::<D, C, _>(&plain, &sites, &Request::default())?.diagram;
        let boxed = t.elapsed().as_secs_f64();
        let total: f64 = d.volumes().iter().sum();
        println!(
            "{D}D n={n}: periodic {periodic:.3} s ({:.2} faces/cell, volume − 1 = {:.1e}), box {boxed:.3} s ({:.2} faces/cell), box volume {}",
            d.neighbor_sites.len() as f64 / n as f64,
            total - 1.0,
            b.neighbor_sites.len() as f64 / n as f64,
            plain.volume(),
        );
    }
    Ok(())
}

fn main() -> Result<(), hcvt_core::CoreError> {
    let mut args = std::env::args().skip(1);
    let d: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(2);
    let n: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(100_000);
    let repeats: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(3);
    let only = args.next();
    if d == 2 {
        run::<2, PolygonCell>(n, repeats, only)
    } else {
        run::<3, PolyhedronCell>(n, repeats, only)
    }
}
