use super::moments::{arc_moments, atan_minus_x, theta_minus_sin};
use super::*;
use crate::diagram::{clipped_cells, clipped_diagram, PolyhedronCell, Request};
use crate::error::CoreError;
use crate::geometry::cross;
use std::f64::consts::PI;

/// Uniform random unit vectors from a fixed generator (Marsaglia's normals).
pub(crate) fn random_sites(n: usize, seed: u64) -> Vec<[f64; 3]> {
    let mut s = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    let mut uniform = move || {
        s ^= s << 13;
        s ^= s >> 7;
        s ^= s << 17;
        (s >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let v = [
            2.0 * uniform() - 1.0,
            2.0 * uniform() - 1.0,
            2.0 * uniform() - 1.0,
        ];
        let r2 = norm2(v);
        if r2 > 1e-6 && r2 <= 1.0 {
            out.push(scale(v, 1.0 / r2.sqrt()));
        }
    }
    out
}

/// The 12 vertices of the icosahedron, unit.
fn icosahedron() -> Vec<[f64; 3]> {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut v = Vec::new();
    for a in [-1.0, 1.0] {
        for b in [-t, t] {
            v.push([0.0, a, b]);
            v.push([a, b, 0.0]);
            v.push([b, 0.0, a]);
        }
    }
    v.into_iter().map(unit).collect()
}

fn diagram(sites: &[[f64; 3]]) -> crate::diagram::Diagram<3> {
    clipped_diagram::<3, PolyhedronCell, _>(&Sphere, sites, &Request::default())
        .unwrap()
        .diagram
}

#[test]
fn the_frame_is_orthonormal_and_right_handed() {
    for site in random_sites(50, 3).into_iter().chain([[0.0, 0.0, -1.0]]) {
        let f = SiteFrame::at(site);
        let m = [f.e1, f.e2, f.z];
        for (a, u) in m.iter().enumerate() {
            for (b, v) in m.iter().enumerate() {
                let want = if a == b { 1.0 } else { 0.0 };
                assert!((dot(*u, *v) - want).abs() < 1e-15);
            }
        }
        assert!((dot(cross(f.e1, f.e2), f.z) - 1.0).abs() < 1e-15);
    }
}

#[test]
fn the_series_agree_with_the_plain_forms() {
    for t in [1e-3, 0.01, 0.1, 0.3, 0.4999] {
        let (a, b) = (theta_minus_sin(t), t - t.sin());
        assert!(
            (a - b).abs() <= 1e-15 * t.powi(3).max(1e-300) + 1e-16 * t,
            "{t}"
        );
    }
    for x in [1e-3, 0.01, 0.05, 0.0999, -0.07] {
        let (a, b) = (atan_minus_x(x), x.atan() - x);
        assert!((a - b).abs() <= 1e-15 * x.abs().powi(3) + 1e-17, "{x}");
    }
    // Where the plain forms have lost every digit, the series keep them.
    let t: f64 = 1e-6;
    let want = t.powi(3) / 6.0 * (1.0 - t * t / 20.0);
    assert!((theta_minus_sin(t) / want - 1.0).abs() < 1e-15);
    let want = -t.powi(3) / 3.0 * (1.0 - 0.6 * t * t);
    assert!((atan_minus_x(t) / want - 1.0).abs() < 1e-15);
}

/// The icosahedron's 12 cells are regular pentagons of area 4π/12; each has 5
/// neighbours, its arcs are all the same, and Σ areas = 4π.
#[test]
fn the_icosahedron_has_twelve_regular_pentagons() {
    let sites = icosahedron();
    let d = diagram(&sites);
    // Pentagon edge: the dodecahedron's, arc between adjacent face centres' duals.
    let arcs = &d.neighbor_measures;
    for (i, m) in d.moments.iter().enumerate() {
        assert!((m.mass - PI / 3.0).abs() < 1e-14, "cell {i}: {}", m.mass);
        let deg = d.neighbor_offsets[i + 1] - d.neighbor_offsets[i];
        assert_eq!(deg, 5, "cell {i}");
        // Centroid on the site's ray: no tangential first moment.
        let t = Sphere.tangent(sites[i], m.first);
        assert!(norm2(t).sqrt() < 1e-15, "cell {i}: {t:?}");
    }
    // The dodecahedron's edge seen from the centre: cos θ = √5/3.
    let theta = (5f64.sqrt() / 3.0).acos();
    for a in arcs {
        assert!((a - theta).abs() < 1e-14, "{a} {theta}");
    }
    let total: f64 = d.volumes().iter().sum();
    assert!((total - 4.0 * PI).abs() < 1e-14);
}

/// Random sites: Σ areas = 4π to 1e-13, Σ (M − A z) + A z = Σ M = 0 (the sphere's
/// first moment), and every arc is listed by both its cells with the same length.
#[test]
fn random_cells_tile_the_sphere() {
    for (n, seed) in [(5, 1), (17, 2), (100, 3), (2000, 4)] {
        let sites = random_sites(n, seed);
        let d = diagram(&sites);
        let total: f64 = d.volumes().iter().sum();
        assert!((total - 4.0 * PI).abs() < 1e-13 * 4.0 * PI, "{n}: {total}");
        let m = (d.moments.iter().zip(&sites)).fold([0.0; 3], |s, (m, &z)| {
            add(s, add(m.first, scale(z, m.mass)))
        });
        assert!(norm2(m).sqrt() < 1e-13, "{n}: {m:?}");
        for i in 0..n {
            for e in d.neighbor_offsets[i]..d.neighbor_offsets[i + 1] {
                let j = d.neighbor_sites[e] as usize;
                let back = (d.neighbor_offsets[j]..d.neighbor_offsets[j + 1])
                    .find(|&f| d.neighbor_sites[f] as usize == i)
                    .unwrap_or_else(|| panic!("{n}: {i}–{j} one-sided"));
                let (a, b) = (d.neighbor_measures[e], d.neighbor_measures[back]);
                assert!((a - b).abs() < 1e-13, "{n}: {i}–{j}: {a} {b}");
            }
        }
        // Euler on the sphere: V − E + F = 2 with trivalent vertices, so E = 3F − 6.
        assert_eq!(d.neighbor_sites.len(), 2 * (3 * n - 6), "{n}");
    }
}

/// Two antipodal sites split the sphere into hemispheres; three on the equator into
/// lunes of 4π/3; a cell reaching past its site's equator (one site against a cluster)
/// is measured through the octants, against a quadrature.
#[test]
fn cells_past_their_sites_equator_are_measured() {
    let d = diagram(&[[0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]);
    for m in &d.moments {
        assert!((m.mass - 2.0 * PI).abs() < 1e-14);
        // ∫(x − z) over a hemisphere: −π z (the centroid at height 1/2): energy 2π.
        assert!((m.second - 2.0 * PI).abs() < 1e-14);
    }
    assert!((d.moments[0].first[2] + PI).abs() < 1e-14);
    assert!((d.neighbor_measures[0] - 2.0 * PI).abs() < 1e-14);
    let third = 2.0 * PI / 3.0;
    let sites: Vec<[f64; 3]> = (0..3)
        .map(|k| [(k as f64 * third).cos(), (k as f64 * third).sin(), 0.0])
        .collect();
    let d = diagram(&sites);
    for m in &d.moments {
        assert!((m.mass - 4.0 * PI / 3.0).abs() < 1e-14);
    }
    // A site on the equator against a cluster at the north pole: its cell reaches
    // far below its own equator (measured through the octants of its frame).
    let mut sites: Vec<[f64; 3]> = (0..5)
        .map(|k| {
            let a = k as f64 * 2.0 * PI / 5.0;
            unit([0.2 * a.cos(), 0.2 * a.sin(), 1.0])
        })
        .collect();
    sites.push([1.0, 0.0, 0.0]);
    let d = diagram(&sites);
    let total: f64 = d.volumes().iter().sum();
    assert!((total - 4.0 * PI).abs() < 1e-13);
    let (area, first, energy) = lat_lon_quadrature(&sites, 5, 2000);
    let m = &d.moments[5];
    assert!(m.mass > 5.0, "{}", m.mass);
    assert!((area - m.mass).abs() < 1e-4 * m.mass, "{area} {}", m.mass);
    for c in 0..3 {
        assert!(
            (first[c] - m.first[c]).abs() < 1e-4 * m.mass,
            "{first:?} {:?}",
            m.first
        );
    }
    assert!(
        (energy - m.second).abs() < 1e-4 * m.second,
        "{energy} {}",
        m.second
    );
}

/// Area, `∫(x − z)` and `∫|x − z|²` over cell `i`, by the midpoint rule on a
/// latitude-longitude grid of `k × 2k` over the whole sphere.
fn lat_lon_quadrature(sites: &[[f64; 3]], i: usize, k: usize) -> (f64, [f64; 3], f64) {
    let z = sites[i];
    let (dt, dp) = (PI / k as f64, PI / k as f64);
    let (mut area, mut first, mut energy) = (0.0, [0.0; 3], 0.0);
    for a in 0..k {
        let t = (a as f64 + 0.5) * dt;
        for b in 0..2 * k {
            let p = (b as f64 + 0.5) * dp;
            let x = [t.sin() * p.cos(), t.sin() * p.sin(), t.cos()];
            if sites.iter().any(|&s| dot(x, s) > dot(x, z)) {
                continue;
            }
            let da = t.sin() * dt * dp;
            area += da;
            first = add(first, scale(sub(x, z), da));
            energy += norm2(sub(x, z)) * da;
        }
    }
    (area, first, energy)
}

/// The first moment and the energy of one cell against a fine quadrature: the cell
/// mapped from the gnomonic plane (`x = (w + ẑ)/√(1 + |w|²)`, `dA = (1 + |w|²)^{-3/2}
/// dw`), midpoint rule on a fine grid over the cell's gnomonic image.
#[test]
fn moments_match_a_quadrature() {
    let sites = random_sites(40, 9);
    let d = diagram(&sites);
    let i = 7;
    let z = sites[i];
    let frame = SiteFrame::at(z);
    // The cell: points closer to z than to every other site.
    let inside = |x: [f64; 3]| sites.iter().all(|&s| dot(x, s) <= dot(x, z) + 1e-300);
    let (k, half) = (1600, 1.5);
    let step = 2.0 * half / k as f64;
    let (mut area, mut first, mut energy) = (0.0, [0.0; 3], 0.0);
    for a in 0..k {
        for b in 0..k {
            let w = [
                -half + (a as f64 + 0.5) * step,
                -half + (b as f64 + 0.5) * step,
            ];
            let r2 = w[0] * w[0] + w[1] * w[1];
            let x = frame.global(scale([w[0], w[1], 1.0], 1.0 / (1.0 + r2).sqrt()));
            if !inside(x) {
                continue;
            }
            let da = step * step / (1.0 + r2).powf(1.5);
            area += da;
            first = add(first, scale(sub(x, z), da));
            energy += norm2(sub(x, z)) * da;
        }
    }
    let m = &d.moments[i];
    // The midpoint rule's error on a cell's staircase edge: ~1e-3 relative at 1600².
    assert!((area - m.mass).abs() < 2e-3 * m.mass, "{area} {}", m.mass);
    let size = m.mass * m.mass.sqrt();
    for c in 0..3 {
        assert!(
            (first[c] - m.first[c]).abs() < 5e-3 * size,
            "{first:?} {:?}",
            m.first
        );
    }
    assert!((energy - m.second).abs() < 5e-3 * m.second);
}

/// A cell's neighbours are found among O(1) sites: every cell of 20,000 random sites
/// and of a tiny cluster depends on the sites within a few spacings only.
#[test]
fn cells_read_sites_within_a_few_spacings() {
    let n = 20_000;
    let sites = random_sites(n, 5);
    let own: Vec<u32> = (0..n as u32).collect();
    let part =
        clipped_cells::<3, PolyhedronCell, _>(&Sphere, &sites, &own, n, &Request::default(), None)
            .unwrap();
    let h2 = 4.0 * PI / n as f64;
    let worst = part.reach2.iter().fold(0.0_f64, |m, &r| m.max(r)) / h2;
    let mean = part.reach2.iter().sum::<f64>() / n as f64 / h2;
    // Reach² in spacings²: πr² of them hold about that many sites times π.
    assert!(worst < 25.0, "worst reach² {worst} spacings²");
    assert!(mean < 7.0, "mean reach² {mean} spacings²");
}

/// The icosahedron's vertices subdivided `k` times: `10·4^k + 2` unit vectors.
fn icosahedral(k: usize) -> Vec<[f64; 3]> {
    let mut v = icosahedron();
    // The 20 faces: triples of vertices pairwise at the edge length.
    let edge2 = (0..12).map(|j| norm2(sub(v[0], v[j]))).filter(|&d| d > 0.0);
    let edge2 = edge2.fold(f64::INFINITY, f64::min) * (1.0 + 1e-9);
    let near = |a: [f64; 3], b: [f64; 3]| norm2(sub(a, b)) <= edge2;
    let mut faces = Vec::new();
    for a in 0..12 {
        for b in a + 1..12 {
            for c in b + 1..12 {
                if near(v[a], v[b]) && near(v[b], v[c]) && near(v[a], v[c]) {
                    faces.push([a, b, c]);
                }
            }
        }
    }
    assert_eq!(faces.len(), 20);
    for _ in 0..k {
        let mut mids = std::collections::HashMap::new();
        let mut mid = |a: usize, b: usize, v: &mut Vec<[f64; 3]>| {
            *mids.entry((a.min(b), a.max(b))).or_insert_with(|| {
                v.push(unit(add(v[a], v[b])));
                v.len() - 1
            })
        };
        let mut next = Vec::new();
        for [a, b, c] in faces {
            let (ab, bc, ca) = (mid(a, b, &mut v), mid(b, c, &mut v), mid(c, a, &mut v));
            next.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        faces = next;
    }
    v
}

/// Cells by number of sides, from the diagram's neighbour lists.
fn sides(d: &crate::diagram::Diagram<3>) -> std::collections::BTreeMap<usize, usize> {
    let mut count = std::collections::BTreeMap::new();
    for i in 0..d.len() {
        *count
            .entry(d.neighbor_offsets[i + 1] - d.neighbor_offsets[i])
            .or_insert(0) += 1;
    }
    count
}

/// Icosahedral sites (k = 1, 2), jittered, go to a spherical CVT by Newton, L-BFGS and
/// Lloyd, to the default rule, with exactly 12 pentagons and the rest hexagons; every
/// site stays on the sphere and the energy goes down.
#[test]
fn icosahedral_sites_converge_to_twelve_pentagons() {
    use crate::optimise::{cvt, Method, Rule, Settings, StopReason};
    use std::ops::ControlFlow;
    for k in [1, 2] {
        let exact = icosahedral(k);
        let n = exact.len();
        assert_eq!(n, 10 * 4usize.pow(k as u32) + 2);
        // Jittered by a tenth of a spacing: the CVT must find the pattern again (k = 1
        // unjittered is a CVT already, by symmetry: every site on an axis of a rotation
        // of the icosahedron).
        let h = (4.0 * PI / n as f64).sqrt();
        let jitter = random_sites(n, 77 + k as u64);
        let sites: Vec<[f64; 3]> = (exact.iter().zip(&jitter))
            .map(|(&x, &r)| unit(add(x, scale(Sphere.tangent(x, r), 0.1 * h))))
            .collect();
        for method in [Method::Newton, Method::Lbfgs, Method::Lloyd] {
            let settings = Settings {
                method,
                max_iter: 2000,
                ..Settings::default()
            };
            let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
            let out = cvt::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &settings, go).unwrap();
            assert_eq!(out.stop_reason, StopReason::Converged, "{k} {method:?}");
            let last = out.history.last().unwrap();
            assert!(Rule::Gap.value(&last.measures) < 1e-7);
            assert!(last.energy < out.history[0].energy, "{k} {method:?}");
            let want = std::collections::BTreeMap::from([(5, 12), (6, n - 12)]);
            assert_eq!(sides(&out.diagram), want, "{k} {method:?}");
            for x in &out.sites {
                assert!((norm2(*x) - 1.0).abs() < 1e-15);
            }
            // At the CVT every site is its cell's constrained centroid.
            for (m, &x) in out.diagram.moments.iter().zip(&out.sites) {
                let c = Sphere.centroid(x, m);
                assert!(norm2(sub(c, x)).sqrt() < 1e-5 * m.mass.sqrt());
            }
        }
    }
}

/// Random sites converge to the default rule by L-BFGS, and to the paper's rule too;
/// every cell ends with 5 to 7 sides mostly, and Σ(6 − sides) = 12 (Euler).
#[test]
fn random_sites_converge() {
    use crate::optimise::{cvt, Method, Rule, Settings, StopReason};
    use std::ops::ControlFlow;
    let sites = random_sites(500, 8);
    for rule in [Rule::Gap, Rule::Paper] {
        let settings = Settings {
            method: Method::Lbfgs,
            rule,
            tol: rule.default_tol(),
            max_iter: 3000,
            ..Settings::default()
        };
        let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
        let out = cvt::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &settings, go).unwrap();
        assert_eq!(out.stop_reason, StopReason::Converged, "{rule:?}");
        let defect: i64 = sides(&out.diagram)
            .iter()
            .map(|(&s, &c)| (6 - s as i64) * c as i64)
            .sum();
        assert_eq!(defect, 12);
        // Mean G of a near-hexagonal spherical CVT: just above the flat hexagon's.
        let last = out.history.last().unwrap();
        assert!(
            last.mean_g > 0.0801 && last.mean_g < 0.0812,
            "{}",
            last.mean_g
        );
    }
    // Newton from random sites: to the same rule in fewer diagrams than L-BFGS.
    let mut diagrams = Vec::new();
    for method in [Method::Newton, Method::Lbfgs] {
        let settings = Settings {
            method,
            max_iter: 3000,
            ..Settings::default()
        };
        let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
        let out = cvt::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &settings, go).unwrap();
        assert_eq!(out.stop_reason, StopReason::Converged, "{method:?}");
        diagrams.push(out.evaluations());
    }
    assert!(
        diagrams[0] < diagrams[1],
        "Newton, L-BFGS diagrams: {diagrams:?}"
    );
}

/// The Riemannian Hessian (arc face terms, projected, with the curvature term) against
/// central differences of the tangent gradient along the retraction
/// `x(t) = (x + t v)/|x + t v|`: `P_x (g(t) − g(−t)) / 2t → Hess[v]`, per site.
#[test]
fn the_hessian_matches_differences_of_the_gradient() {
    use crate::optimise::{evaluate, PointRequest};
    // A cluster at the north pole and a site on the equator, whose cell reaches far
    // below its own equator (measured through the octants), then random sites.
    let mut cluster: Vec<[f64; 3]> = (0..5)
        .map(|k| {
            let a = k as f64 * 2.0 * PI / 5.0 + 0.1;
            unit([0.2 * a.cos(), 0.2 * a.sin(), 1.0])
        })
        .collect();
    cluster.push([1.0, 0.0, 0.0]);
    let cases = [
        (cluster, 5),
        (random_sites(60, 3), 3),
        (random_sites(400, 4), 4),
    ];
    for (sites, seed) in cases {
        let n = sites.len();
        let h = (4.0 * PI / n as f64).sqrt();
        let request = PointRequest {
            hessian: true,
            density: None,
        };
        let point = evaluate::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &request).unwrap();
        let v: Vec<[f64; 3]> = (random_sites(n, seed + 100).iter().zip(&sites))
            .map(|(&r, &x)| Sphere.tangent(x, r))
            .collect();
        let hv = point.hessian_product(&v).unwrap();
        let t = 1e-6 * h;
        let moved = |s: f64| {
            let x: Vec<[f64; 3]> = (sites.iter().zip(&v))
                .map(|(&x, &d)| Sphere.retract(add(x, scale(d, s * t))))
                .collect();
            evaluate::<3, PolyhedronCell, _>(&Sphere, x, &PointRequest::default())
                .unwrap()
                .gradient
        };
        let (plus, minus) = (moved(1.0), moved(-1.0));
        let scale_hv = hv.iter().map(|&r| norm2(r)).fold(0.0, f64::max).sqrt();
        let mut worst: f64 = 0.0;
        for i in 0..n {
            let fd = Sphere.tangent(sites[i], scale(sub(plus[i], minus[i]), 0.5 / t));
            worst = worst.max(norm2(sub(fd, hv[i])).sqrt() / scale_hv);
            // The Hessian maps into the tangent plane.
            assert!(dot(hv[i], sites[i]).abs() < 1e-13 * scale_hv);
        }
        let tol = 1e-7;
        assert!(worst < tol, "{n}: worst relative miss {worst:e}");
        // Without the curvature term the miss is of the cells' energy: far above that.
        let curvature: f64 = point.diagram.moments.iter().map(|m| m.second).sum::<f64>() / n as f64;
        let v_norm = v.iter().map(|&r| norm2(r)).fold(0.0, f64::max).sqrt();
        assert!(
            curvature * v_norm > 100.0 * tol * scale_hv,
            "{curvature} {v_norm} {scale_hv}"
        );
    }
}

/// The Riemannian Hessian (its arc terms and its projection in parallel) is the same
/// bit for bit on 1 and 3 threads.
#[test]
fn the_hessian_does_not_depend_on_the_thread_count() {
    use crate::optimise::{evaluate, PointRequest};
    let sites = random_sites(3000, 6);
    let request = PointRequest {
        hessian: true,
        density: None,
    };
    let hessian = |threads: usize| {
        crate::on_threads::on_threads(threads, || {
            evaluate::<3, PolyhedronCell, _>(&Sphere, sites.clone(), &request)
                .unwrap()
                .hessian
                .unwrap()
        })
    };
    let (one, three) = (hessian(1), hessian(3));
    assert_eq!(one.diagonal, three.diagonal);
    assert_eq!(one.off_diagonal, three.off_diagonal);
}

/// An arc's moments about the site against a Gauss–Legendre rule along it.
#[test]
fn arc_moments_match_a_quadrature() {
    for (a, b) in [
        ([0.01, 0.02, 1.0], [-0.015, 0.012, 1.0]),
        ([0.3, -0.2, 0.9], [0.5, 0.4, 0.7]),
        ([1.0, 0.0, 0.0], [0.0, 0.7, -0.7]),
    ] {
        let (a, b) = (unit(a), unit(b));
        let theta = dot(a, b).clamp(-1.0, 1.0).acos();
        let m = arc_moments(a, b, theta);
        let n = unit(cross(a, b));
        let u = cross(n, a);
        // 20 Gauss–Legendre nodes on [0, θ].
        let (mut first, mut second) = ([0.0; 3], [[0.0; 3]; 3]);
        for (x, w) in gauss_legendre(20) {
            let w = w * 0.5 * theta;
            let tt = 0.5 * theta * (x + 1.0);
            let y = sub(add(scale(a, tt.cos()), scale(u, tt.sin())), [0.0, 0.0, 1.0]);
            for p in 0..3 {
                first[p] += w * y[p];
                for q in 0..3 {
                    second[p][q] += w * y[p] * y[q];
                }
            }
        }
        let size = norm2(sub(a, [0.0, 0.0, 1.0])).max(norm2(sub(b, [0.0, 0.0, 1.0])));
        for p in 0..3 {
            assert!(
                (first[p] - m.first[p]).abs() < 1e-14 * theta,
                "{first:?} {:?}",
                m.first
            );
            for (q, (s, t)) in second[p].iter().zip(&m.second[p]).enumerate() {
                let e = (s - t).abs();
                assert!(e < 1e-14 * theta * size, "{p}{q}: {e:e}");
            }
        }
    }
}

/// The `k` Gauss–Legendre nodes and weights on [−1, 1], by Newton on `P_k`.
pub(crate) fn gauss_legendre(k: usize) -> Vec<(f64, f64)> {
    (1..=k)
        .map(|r| {
            let mut x = (PI * (r as f64 - 0.25) / (k as f64 + 0.5)).cos();
            let mut dp = 0.0;
            for _ in 0..100 {
                let (mut p0, mut p1) = (1.0, x);
                for l in 2..=k {
                    let l = l as f64;
                    (p0, p1) = (p1, ((2.0 * l - 1.0) * x * p1 - (l - 1.0) * p0) / l);
                }
                dp = k as f64 * (x * p1 - p0) / (x * x - 1.0);
                x -= p1 / dp;
            }
            (x, 2.0 / ((1.0 - x * x) * dp * dp))
        })
        .collect()
}

#[test]
fn sites_off_the_sphere_are_refused_by_row() {
    let mut sites = random_sites(30, 2);
    sites[11] = scale(sites[11], 1.0 + 1e-6);
    let err =
        clipped_diagram::<3, PolyhedronCell, _>(&Sphere, &sites, &Request::default()).unwrap_err();
    assert!(
        matches!(err, CoreError::SiteOutsideDomain { index: 11, .. }),
        "{err:?}"
    );
    // Normalised vectors are accepted; duplicates are named.
    sites[11] = unit(sites[11]);
    sites[20] = sites[3];
    let err =
        clipped_diagram::<3, PolyhedronCell, _>(&Sphere, &sites, &Request::default()).unwrap_err();
    assert!(matches!(
        err,
        CoreError::DuplicateSites {
            first: 3,
            second: 20,
            ..
        }
    ));
}
