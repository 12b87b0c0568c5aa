//! Time CVTs of uniform random sites, for profiling the optimisation loop.
//! `cargo run --release --example cvt_profile -- square 1000 [lbfgs|newton|lloyd] [seed]
//! [repeats] [paper|gap]` (or `star 2000`): the run to the paper's rule (`‖g‖/‖X‖ < 1e-10`
//! in input coordinates; `gap` for the default rule), then `repeats` (default 50, 0 to skip)
//! diagrams of the final sites alone, with the Hessian for Newton.

use std::ops::ControlFlow;
use std::time::Instant;

use hcvt_core::sample::interior_sites;
use hcvt_core::{cvt, evaluate, Method, PointRequest, Polygon, PolygonCell, Rule, Settings};

fn main() -> Result<(), hcvt_core::CoreError> {
    let mut args = std::env::args().skip(1);
    let shape = args.next().unwrap_or_else(|| "square".into());
    let n: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(1000);
    let method = match args.next().as_deref() {
        Some("newton") => Method::Newton,
        Some("lloyd") => Method::Lloyd,
        _ => Method::Lbfgs,
    };
    let seed: u64 = args.next().and_then(|a| a.parse().ok()).unwrap_or(7);
    let repeats: usize = args.next().and_then(|a| a.parse().ok()).unwrap_or(50);
    let rule = match args.next().as_deref() {
        Some("gap") => Rule::Gap,
        _ => Rule::Paper,
    };
    let settings = Settings {
        method,
        rule,
        tol: rule.default_tol(),
        ..Settings::default()
    };
    let ring: Vec<[f64; 2]> = if shape == "star" {
        // The paper's five-branch star (hcvt.shapes.star), area about 117.5.
        let inner = 18f64.to_radians().sin() / 126f64.to_radians().sin();
        (0..10)
            .map(|k| {
                let t = std::f64::consts::FRAC_PI_2 + k as f64 * std::f64::consts::PI / 5.0;
                let r = 8.1 * if k % 2 == 0 { 1.0 } else { inner };
                [r * t.cos(), r * t.sin()]
            })
            .collect()
    } else {
        vec![[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]]
    };
    let m = ring.len() as u32;
    let domain = Polygon::new(ring, (0..m).map(|k| [k, (k + 1) % m]).collect())?;
    let sites = interior_sites(&domain, n, seed);
    let t = Instant::now();
    // On a worker thread, as the Python binding runs it: parallel steps are then forks,
    // not hand-offs from outside the pool.
    let pool = rayon::ThreadPoolBuilder::new()
        .build()
        .expect("a thread pool");
    let out = pool.install(|| {
        cvt::<2, PolygonCell, _>(&domain, sites, &settings, &mut |_, _| {
            ControlFlow::Continue(())
        })
    })?;
    let seconds = t.elapsed().as_secs_f64();
    println!(
        "{shape} n = {n}, {} rule: {} in {} iterations, {} diagrams, {seconds:.3} s ({:.3} ms per diagram)",
        rule.as_str(),
        out.stop_reason.as_str(),
        out.iterations(),
        out.evaluations(),
        1e3 * seconds / out.evaluations() as f64
    );
    if repeats == 0 {
        return Ok(());
    }
    let hessian = method == Method::Newton;
    let t = Instant::now();
    for _ in 0..repeats {
        evaluate::<2, PolygonCell, _>(
            &domain,
            out.sites.clone(),
            &PointRequest {
                hessian,
                density: None,
            },
        )?;
    }
    println!(
        "one diagram alone: {:.3} ms",
        1e3 * t.elapsed().as_secs_f64() / repeats as f64
    );
    Ok(())
}
