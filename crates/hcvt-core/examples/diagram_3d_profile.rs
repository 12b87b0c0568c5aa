//! Time 3D clipped diagrams and CVTs, for profiling the cell clipping.
//!
//! `cargo run --release --example diagram_3d_profile -- MESH SITES [diagrams] [MODE]`:
//! `MESH` names two whitespace-separated text files, `MESH_v.txt` (one vertex `x y z` a
//! line) and `MESH_f.txt` (one triangle `a b c` a line), e.g. written from Python with
//! `numpy.savetxt` of `hcvt.load_domain(path).vertices` and `.faces`; `SITES` is a text
//! file of sites, one `x y z` a line. Times `diagrams` diagrams (default 20); `MODE` is
//! `hessian` (the diagrams carry the Hessian), `cvt` (then an L-BFGS CVT from those sites)
//! or `newton` (a Newton CVT).

#[path = "common/rows.rs"]
mod rows;

use std::ops::ControlFlow;
use std::time::Instant;

use hcvt_core::{cvt, evaluate, Method, PointRequest, PolyhedronCell, Settings, Solid};
use rows::read_rows;

fn main() -> Result<(), hcvt_core::CoreError> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [mesh, sites_path] = [0, 1].map(|k| {
        args.get(k)
            .map(String::as_str)
            .expect("usage: diagram_3d_profile MESH SITES [diagrams] [hessian|cvt|newton]")
    });
    let repeat: usize = args.get(2).and_then(|a| a.parse().ok()).unwrap_or(20);
    let mode = args.get(3).map_or("", String::as_str);
    let hessian = mode == "hessian";
    let vertices: Vec<[f64; 3]> = read_rows(&format!("{mesh}_v.txt"));
    let faces: Vec<[u32; 3]> = read_rows(&format!("{mesh}_f.txt"));
    let domain = Solid::new(vertices, faces)?;
    let sites: Vec<[f64; 3]> = read_rows(sites_path);
    let n = sites.len();
    let t = Instant::now();
    let mut energy = 0.0;
    for _ in 0..repeat {
        energy = evaluate::<3, PolyhedronCell, _>(
            &domain,
            sites.clone(),
            &PointRequest {
                hessian,
                density: None,
            },
        )?
        .energy;
    }
    println!(
        "{n} sites: {:.3} ms per diagram, energy {energy:.17e}",
        1e3 * t.elapsed().as_secs_f64() / repeat.max(1) as f64
    );
    if mode == "cvt" || mode == "newton" {
        let settings = Settings {
            method: if mode == "newton" {
                Method::Newton
            } else {
                Method::Lbfgs
            },
            ..Settings::default()
        };
        let t = Instant::now();
        let out = cvt::<3, PolyhedronCell, _>(&domain, sites, &settings, &mut |_, _| {
            ControlFlow::Continue(())
        })?;
        let seconds = t.elapsed().as_secs_f64();
        println!(
            "CVT: {} in {} iterations, {} diagrams, {seconds:.3} s ({:.3} ms per diagram)",
            out.stop_reason.as_str(),
            out.iterations(),
            out.evaluations(),
            1e3 * seconds / out.evaluations() as f64
        );
    }
    Ok(())
}
