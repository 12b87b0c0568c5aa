//! Time the diagram of random sites on the unit sphere.
//! `cargo run --release --example sphere_profile -- 40962 [repeats]`

use std::time::Instant;

use hcvt_core::sample::Lcg;
use hcvt_core::{clipped_diagram, PolyhedronCell, Request, Sphere};

fn main() -> Result<(), hcvt_core::CoreError> {
    let mut args = std::env::args().skip(1);
    let n: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(40_962);
    let repeats: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(3);
    let mut rng = Lcg::new(7);
    let sites: Vec<[f64; 3]> = (0..n)
        .map(|_| loop {
            let v: [f64; 3] = std::array::from_fn(|_| 2.0 * rng.unit() - 1.0);
            let r2: f64 = v.iter().map(|c| c * c).sum();
            if r2 > 1e-4 && r2 <= 1.0 {
                break v.map(|c| c / r2.sqrt());
            }
        })
        .collect();
    if std::env::args().nth(3).as_deref() == Some("newton") {
        use hcvt_core::{cvt, evaluate, Method, PointRequest, Settings};
        for hessian in [false, true] {
            let t = Instant::now();
            let request = PointRequest {
                hessian,
                density: None,
            };
            let p = evaluate::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &request)?;
            println!(
                "evaluate hessian={hessian}: {:.3} s",
                t.elapsed().as_secs_f64()
            );
            if let Some(h) = &p.hessian {
                let t = Instant::now();
                for _ in 0..10 {
                    let _ = h.product(&p.diagram, &p.gradient);
                }
                println!("10 products: {:.3} s", t.elapsed().as_secs_f64());
            }
        }
        if std::env::args().nth(4).as_deref() == Some("only") {
            return Ok(());
        }
        let settings = Settings {
            method: Method::Newton,
            ..Settings::default()
        };
        let t = Instant::now();
        let out = cvt::<3, PolyhedronCell, _>(&Sphere, sites, &settings, &mut |r, _| {
            println!(
                "  {:.3} s  {} diagrams  gap {:.2e}",
                r.seconds, r.evaluations, r.measures.rms_gap
            );
            std::ops::ControlFlow::Continue(())
        })?;
        println!(
            "newton: {:.3} s, {:?}",
            t.elapsed().as_secs_f64(),
            out.stop_reason
        );
        return Ok(());
    }
    for _ in 0..repeats {
        let t = Instant::now();
        let d =
            clipped_diagram::<3, PolyhedronCell, _>(&Sphere, &sites, &Request::default())?.diagram;
        let total: f64 = d.volumes().iter().sum();
        println!(
            "sphere n={n}: {:.3} s ({:.2} faces/cell, area − 4π = {:.1e})",
            t.elapsed().as_secs_f64(),
            d.neighbor_sites.len() as f64 / n as f64,
            total - 4.0 * std::f64::consts::PI,
        );
    }
    Ok(())
}
