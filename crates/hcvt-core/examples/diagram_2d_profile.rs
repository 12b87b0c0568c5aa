//! Time the stages of one 2D diagram of uniform random sites in the unit square.
//! `cargo run --release --example diagram_2d_profile -- 1000000`

use std::time::Instant;

use hcvt_core::sample::Lcg;
use hcvt_core::{clipped_diagram, DomainKind, Polygon, PolygonCell, Request, SiteIndex};
use rayon::prelude::*;

fn main() -> Result<(), hcvt_core::CoreError> {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(1_000_000);
    let square = Polygon::new(
        vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]],
        vec![[0, 1], [1, 2], [2, 3], [3, 0]],
    )?;
    let mut rng = Lcg::new(7);
    let sites: Vec<[f64; 2]> = (0..n).map(|_| [rng.unit(), rng.unit()]).collect();
    let t = Instant::now();
    let w: Vec<_> = sites
        .par_iter()
        .map(|s| DomainKind::locate(&square, s))
        .collect();
    println!(
        "winding numbers {:.3} s ({})",
        t.elapsed().as_secs_f64(),
        w.len()
    );
    let t = Instant::now();
    let index = SiteIndex::new(&sites)?;
    println!("index build     {:.3} s", t.elapsed().as_secs_f64());
    let t = Instant::now();
    let k: usize = sites.par_iter().map(|s| index.nearest(*s, 17).len()).sum();
    println!("kNN 17          {:.3} s ({k})", t.elapsed().as_secs_f64());
    for _ in 0..6 {
        let t = Instant::now();
        let d = clipped_diagram::<2, PolygonCell, _>(&square, &sites, &Request::default())
            .map(|c| c.diagram)?;
        println!(
            "full diagram    {:.3} s (area {})",
            t.elapsed().as_secs_f64(),
            d.volumes().iter().sum::<f64>()
        );
    }
    Ok(())
}
