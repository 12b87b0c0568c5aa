//! Time 3D diagrams of uniform random sites in the unit cube, to check that the nearest-site
//! index serves 3D as well as 2D.
//! `cargo run --release --example diagram_3d_profile -- 20000`

use std::time::Instant;

use hcvt_core::diagram::{clipped_diagram, Options, PolyhedronCell};
use hcvt_core::domain::Solid;

fn main() -> Result<(), hcvt_core::CoreError> {
    let n: usize = std::env::args()
        .nth(1)
        .and_then(|a| a.parse().ok())
        .unwrap_or(20_000);
    let cube = Solid::cuboid([0.0; 3], [1.0; 3])?;
    let mut state = 7u64;
    let mut rand = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (state >> 11) as f64 / (1u64 << 53) as f64
    };
    let sites: Vec<[f64; 3]> = (0..n).map(|_| [rand(), rand(), rand()]).collect();
    for _ in 0..5 {
        let t = Instant::now();
        let (d, _) =
            clipped_diagram::<3, PolyhedronCell>(&cube, &sites, Options::default(), false)?;
        println!(
            "full diagram    {:.3} s (volume {})",
            t.elapsed().as_secs_f64(),
            d.volumes().iter().sum::<f64>()
        );
    }
    Ok(())
}
