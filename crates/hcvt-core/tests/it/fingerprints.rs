//! Fingerprints of diagrams and CVT runs, recorded before the refactor of issue 15: every
//! bit of the moments, neighbours, face measures, Hessian blocks and kept cells of fixed
//! cases (2D square, star and polygon with holes; 3D ball and real meshes of
//! `../shared/data/3d`, several seeded site sets each), and the iteration and diagram
//! counts and final sites of short Lloyd, L-BFGS and Newton runs.
//!
//! A change of behaviour, however small, changes a hash. When a change is meant (a better
//! algorithm, not a refactor), say so in its commit and record the new values printed by
//! `cargo test --release --test it fingerprints:: -- --nocapture`.

use crate::common::{data_3d, interior_sites, polygon, read_mesh};

use std::ops::ControlFlow;

use hcvt_core::{
    clipped_diagram, cvt, evaluate, Boundary, ConvexCell, Diagram, DomainKind, Euclid, Face,
    Method, Options, Point, PointRequest, Polygon, PolygonCell, PolyhedronCell, Request, Rule,
    Settings, Solid, Space,
};

/// FNV-1a over 64-bit words: the same value on every platform and compiler.
#[derive(Clone, Copy)]
struct Hash(u64);

impl Hash {
    fn new() -> Self {
        Self(0xcbf2_9ce4_8422_2325)
    }

    fn word(&mut self, w: u64) {
        for byte in w.to_le_bytes() {
            self.0 = (self.0 ^ byte as u64).wrapping_mul(0x0000_0100_0000_01b3);
        }
    }

    fn f(&mut self, x: f64) {
        self.word(x.to_bits());
    }

    fn fs(&mut self, xs: &[f64]) {
        xs.iter().for_each(|&x| self.f(x));
    }

    fn face(&mut self, face: Face) {
        match face {
            Face::Box => self.word(1 << 40),
            Face::Neighbor(j) => self.word((2 << 40) | j as u64),
            Face::Boundary(t) => self.word((3 << 40) | t as u64),
            Face::Cone => self.word(4 << 40),
        }
    }
}

fn hash_diagram<const D: usize>(h: &mut Hash, d: &Diagram<D>) {
    for m in &d.moments {
        h.f(m.mass);
        h.fs(&m.first);
        h.f(m.second);
    }
    h.fs(&d.boundary_measure);
    d.neighbor_offsets.iter().for_each(|&o| h.word(o as u64));
    d.neighbor_sites.iter().for_each(|&j| h.word(j as u64));
    h.fs(&d.neighbor_measures);
}

/// The Hessian's blocks, diagonal then off-diagonal, when the point carries them.
fn hash_hessian<const D: usize>(h: &mut Hash, point: &Point<D>) {
    let hessian = point.hessian.as_ref().expect("asked for the Hessian");
    for block in hessian.diagonal.iter().chain(&hessian.off_diagonal) {
        block.iter().for_each(|row| h.fs(row));
    }
}

fn square() -> Polygon {
    polygon(&[&[[0.0, 0.0], [20.0, 0.0], [20.0, 20.0], [0.0, 20.0]]])
}

/// The regular pentagram of `../shared/data/2d/star5.geojson`: outer radius 1, inner
/// radius sin 18° / sin 126°, first tip at +y, counter-clockwise.
fn star() -> Polygon {
    let inner = 18f64.to_radians().sin() / 126f64.to_radians().sin();
    let ring: Vec<[f64; 2]> = (0..10)
        .map(|k| {
            let r = if k % 2 == 0 { 1.0 } else { inner };
            let t = std::f64::consts::FRAC_PI_2 + k as f64 * std::f64::consts::PI / 5.0;
            [r * t.cos(), r * t.sin()]
        })
        .collect();
    polygon(&[&ring])
}

/// An L with two holes, one of them touching nothing, one a thin slot.
fn holes() -> Polygon {
    polygon(&[
        &[[0., 0.], [4., 0.], [4., 2.], [2., 2.], [2., 4.], [0., 4.]],
        &[[0.5, 0.5], [0.5, 1.0], [1.0, 1.0], [1.0, 0.5]],
        &[[2.5, 0.9], [2.5, 1.0], [3.5, 1.0], [3.5, 0.9]],
    ])
}

/// The diagram with and without the Hessian, and with the cells kept.
fn hash_2d(boundary: &Polygon, sites: &[[f64; 2]], options: Options) -> u64 {
    let mut h = Hash::new();
    let (d, cells) = clipped_diagram::<2, PolygonCell, _>(
        boundary,
        sites,
        &Request {
            options,
            keep_cells: true,
            ..Request::default()
        },
    )
    .map(|c| (c.diagram, c.cells))
    .unwrap();
    hash_diagram(&mut h, &d);
    for cell in &cells {
        cell.vertices().iter().for_each(|v| h.fs(v));
        cell.faces().iter().for_each(|&f| h.face(f));
    }
    if !options.allow_outside {
        let point = evaluate::<2, PolygonCell, _>(
            boundary,
            sites.to_vec(),
            &PointRequest {
                hessian: true,
                density: None,
            },
        )
        .unwrap();
        hash_diagram(&mut h, &point.diagram);
        hash_hessian(&mut h, &point);
    }
    h.0
}

fn hash_3d(boundary: &Solid, sites: &[[f64; 3]]) -> u64 {
    let mut h = Hash::new();
    let (d, cells) = clipped_diagram::<3, PolyhedronCell, _>(
        boundary,
        sites,
        &Request {
            options: Options::default(),
            keep_cells: true,
            ..Request::default()
        },
    )
    .map(|c| (c.diagram, c.cells))
    .unwrap();
    hash_diagram(&mut h, &d);
    for cell in &cells {
        cell.vertices().iter().for_each(|v| h.fs(v));
        cell.for_each_polygon(|face, polygon| {
            h.face(face);
            polygon.iter().for_each(|v| h.fs(v));
        });
    }
    let point = evaluate::<3, PolyhedronCell, _>(
        boundary,
        sites.to_vec(),
        &PointRequest {
            hessian: true,
            density: None,
        },
    )
    .unwrap();
    hash_diagram(&mut h, &point.diagram);
    hash_hessian(&mut h, &point);
    h.0
}

/// Compare `found` with `recorded` by name; print every value so that a meant change can be
/// recorded in one go. Without the shared data (`data_3d`), the meshes' cases are left out.
fn check(found: &[(String, u64)], recorded: &[(&str, u64)]) {
    let mut wrong = Vec::new();
    for (name, value) in found {
        println!("        (\"{name}\", 0x{value:016x}),");
        match recorded.iter().find(|(n, _)| n == name) {
            Some(&(_, r)) if r == *value => {}
            Some(&(_, r)) => wrong.push(format!("{name}: 0x{value:016x}, recorded 0x{r:016x}")),
            None => wrong.push(format!("{name}: 0x{value:016x}, nothing recorded")),
        }
    }
    if data_3d().is_some() {
        assert_eq!(found.len(), recorded.len(), "cases: {found:?}");
    } else {
        eprintln!("../shared/data/3d not found: its meshes' cases skipped");
    }
    assert!(wrong.is_empty(), "changed:\n{}", wrong.join("\n"));
}

const DIAGRAMS: &[(&str, u64)] = &[
    ("square seed 0", 0xa30cd2e1457857b6),
    ("square seed 1", 0xd8199c02983fd230),
    ("square seed 2", 0xf90b2d0cd4a7bc2f),
    ("star seed 0", 0x4ac641b4eda3dd17),
    ("star seed 1", 0x75576d6215fd740d),
    ("star seed 2", 0x882bfea5071ad75e),
    ("holes seed 0", 0x90149c3f9b171528),
    ("holes seed 1", 0x5ba48e0f531ea410),
    ("holes seed 2", 0x74efef4fcf37227e),
    ("square lattice", 0x4a45c217703dcb0c),
    ("square outside", 0x30083d310308cb7c),
    ("ball seed 0", 0x4bdbf0659353b82d),
    ("ball seed 1", 0x8151ed10ee2d1d8e),
    ("fandisk seed 0", 0x15c8802f083965f6),
    ("fandisk seed 1", 0xd6e405b0aa308278),
    ("cheese seed 0", 0x2fabc019a03547c4),
    ("cheese seed 1", 0x943a0818e794b8aa),
    ("cube lattice", 0x4898d692dc613280),
];

#[test]
fn diagrams_match_their_recorded_hashes() {
    let mut found = Vec::new();
    for (name, boundary, n) in [
        ("square", square(), 400),
        ("star", star(), 300),
        ("holes", holes(), 300),
    ] {
        for seed in 0..3 {
            let sites = interior_sites(&boundary, n, seed);
            let value = hash_2d(&boundary, &sites, Options::default());
            found.push((format!("{name} seed {seed}"), value));
        }
    }
    // A lattice with cell faces on the square's sides, and sites outside the square.
    let lattice: Vec<[f64; 2]> = (0..100)
        .map(|k| [(k % 10) as f64 * 2.0 + 1.0, (k / 10) as f64 * 2.0 + 1.0])
        .collect();
    found.push((
        "square lattice".into(),
        hash_2d(&square(), &lattice, Options::default()),
    ));
    let mut outside = interior_sites(&square(), 200, 7);
    outside[3] = [-1.5, 4.0];
    outside[77] = [25.0, 30.0];
    let allow = Options {
        allow_outside: true,
    };
    found.push(("square outside".into(), hash_2d(&square(), &outside, allow)));
    let meshes = [("ball", "sphere.ply", 300), ("fandisk", "fandisk.off", 400)];
    for (name, file, n) in meshes.into_iter().chain([("cheese", "cheese.off", 400)]) {
        let Some(dir) = data_3d() else { break };
        let solid = read_mesh(&dir.join(file));
        for seed in 0..2 {
            let sites = interior_sites(&solid, n, seed);
            found.push((format!("{name} seed {seed}"), hash_3d(&solid, &sites)));
        }
    }
    let cube = Solid::cuboid([0.0; 3], [1.0; 3]).unwrap();
    let grid: Vec<[f64; 3]> = (0..125)
        .map(|k| [k % 5, (k / 5) % 5, k / 25].map(|x| (x as f64 + 0.5) / 5.0))
        .collect();
    found.push(("cube lattice".into(), hash_3d(&cube, &grid)));
    check(&found, DIAGRAMS);
}

const RUNS: &[(&str, u64)] = &[
    (
        "Lloyd Gap star: 60 iterations, 61 diagrams",
        0x415d7d59c23b3ddb,
    ),
    (
        "Lloyd Gap holes: 60 iterations, 61 diagrams",
        0x2b2a8da223a5d4b1,
    ),
    (
        "Lloyd Gap ball: 60 iterations, 61 diagrams",
        0x5b772e8a6fe45953,
    ),
    (
        "Lbfgs Gap star: 162 iterations, 174 diagrams",
        0x67d25744aabc72f4,
    ),
    (
        "Lbfgs Gap holes: 113 iterations, 120 diagrams",
        0x73b8ca0f510539ea,
    ),
    (
        "Lbfgs Gap ball: 261 iterations, 267 diagrams",
        0xc47ba1a0e30bdd70,
    ),
    (
        "Newton Gap star: 31 iterations, 34 diagrams",
        0x455291d0a5947ed1,
    ),
    (
        "Newton Gap holes: 47 iterations, 53 diagrams",
        0xc5e0cb17ee793b4f,
    ),
    (
        "Newton Gap ball: 53 iterations, 58 diagrams",
        0x2d92739f7790526d,
    ),
    (
        "Lbfgs Paper star: 165 iterations, 177 diagrams",
        0xc8caae7bcc79426d,
    ),
    (
        "Lbfgs Paper holes: 129 iterations, 137 diagrams",
        0x3f2a74c4f8b3501c,
    ),
    (
        "Lbfgs Paper ball: 332 iterations, 340 diagrams",
        0x1c20e0abcb5fb841,
    ),
];

/// Iterations, diagrams, stop reason, every record but its seconds, and the final sites.
fn hash_run<const D: usize>(out: &hcvt_core::Outcome<D>) -> u64 {
    let mut h = Hash::new();
    h.word(out.iterations() as u64);
    h.word(out.evaluations() as u64);
    h.word(out.stop_reason as u64);
    for r in &out.history {
        let m = &r.measures;
        h.fs(&[r.energy, r.mean_g, m.rms_gap, m.max_gap, m.grad_norm]);
        h.word(m.pinned as u64);
        h.word(r.evaluations as u64);
        h.word(r.step as u64);
    }
    out.sites.iter().for_each(|s| h.fs(s));
    hash_diagram(&mut h, &out.diagram);
    h.0
}

/// A short CVT of `n` sites of seed 3 in `boundary`: its name with the counts of
/// iterations and diagrams, and its hash.
fn run<const D: usize, C: ConvexCell<D>>(
    name: &str,
    boundary: &Boundary<D>,
    n: usize,
    settings: &Settings<'_, D>,
) -> (String, u64)
where
    Euclid: Space<D>,
    Boundary<D>: DomainKind<D>,
{
    let sites = interior_sites(boundary, n, 3);
    let go = &mut |_: &_, _: &_| ControlFlow::Continue(());
    let out = cvt::<D, C, _>(boundary, sites, settings, go).unwrap();
    let (iterations, diagrams) = (out.iterations(), out.evaluations());
    let (method, rule) = (settings.method, settings.rule);
    let name = format!("{method:?} {rule:?} {name}: {iterations} iterations, {diagrams} diagrams");
    (name, hash_run(&out))
}

#[test]
fn cvt_runs_match_their_recorded_hashes() {
    let mut found = Vec::new();
    let runs = [
        (Method::Lloyd, Rule::Gap),
        (Method::Lbfgs, Rule::Gap),
        (Method::Newton, Rule::Gap),
        (Method::Lbfgs, Rule::Paper),
    ];
    for (method, rule) in runs {
        fn settings<const D: usize>(method: Method, rule: Rule) -> Settings<'static, D> {
            Settings {
                method,
                rule,
                tol: rule.default_tol(),
                max_iter: if method == Method::Lloyd { 60 } else { 400 },
                ..Settings::default()
            }
        }
        let plane = settings::<2>(method, rule);
        found.push(run::<2, PolygonCell>("star", &star(), 200, &plane));
        found.push(run::<2, PolygonCell>("holes", &holes(), 150, &plane));
        if let Some(dir) = data_3d() {
            let ball = read_mesh(&dir.join("sphere.ply"));
            let space = settings::<3>(method, rule);
            found.push(run::<3, PolyhedronCell>("ball", &ball, 150, &space));
        }
    }
    check(&found, RUNS);
}
