//! `mesh_quality` on conforming meshes of real diagrams: the cells' volumes from the faces
//! equal the diagram's exact moments (a different computation, signed cones from the
//! sites) and sum to the domain, and the result does not depend on the thread count.
//!
//! Centroids are exact only where every face is convex: OpenFOAM's face centre weights its
//! fan's triangles by their unsigned areas, which is not the centroid of a non-convex face
//! (a piece of a bisector cut by a non-convex domain), and we follow OpenFOAM. They are
//! checked in convex domains.

use crate::common::{data_3d, dented_cube, interior_sites, polygon, read_mesh};

use hcvt_core::{
    clipped_diagram, conforming_mesh, mesh_quality, Boundary, ConvexCell, Diagram, DomainKind,
    Euclid, MeshArrays, MeshDomain, MeshQuality, Options, PolygonCell, PolyhedronCell, Request,
    Solid, Space,
};

fn measured<const D: usize, C, K>(domain: &K, sites: &[[f64; D]]) -> (Diagram<D>, MeshQuality<D>)
where
    C: ConvexCell<D>,
    K: DomainKind<D> + MeshDomain<D>,
    Euclid: Space<D>,
{
    let n = sites.len();
    let diagram = clipped_diagram::<D, C, _>(domain, sites, &Request::default())
        .unwrap()
        .diagram;
    let mesh = conforming_mesh(domain, sites, Options::default()).unwrap();
    let quality = mesh_quality(&MeshArrays::of(&mesh, n), None).unwrap();
    for threads in [1, 3] {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        let again = pool.install(|| mesh_quality(&MeshArrays::of(&mesh, n), None).unwrap());
        assert!(
            bitwise_equal(&again, &quality),
            "{threads} threads changed a bit"
        );
    }
    (diagram, quality)
}

/// Equal to the last bit, NaN matching NaN.
fn bitwise_equal<const D: usize>(a: &MeshQuality<D>, b: &MeshQuality<D>) -> bool {
    let bits = |q: &MeshQuality<D>| -> Vec<u64> {
        let rows = q
            .face_centre
            .iter()
            .chain(&q.area_vector)
            .chain(&q.centroid);
        rows.flatten()
            .chain(&q.volume)
            .chain(&q.aspect_ratio)
            .chain(&q.non_orthogonality)
            .chain(&q.skewness)
            .chain(&q.volume_ratio)
            .map(|x| x.to_bits())
            .collect()
    };
    bits(a) == bits(b) && a.inverted_pyramid == b.inverted_pyramid
}

/// Volumes to `1e-12` of the cell, total to `1e-13`; with `convex`, centroids to `1e-12`
/// of the cell's size.
fn assert_moments<const D: usize>(
    convex: bool,
    d: &Diagram<D>,
    q: &MeshQuality<D>,
    sites: &[[f64; D]],
    total: f64,
) {
    for (i, m) in d.moments.iter().enumerate() {
        let v = q.volume[i];
        assert!(
            (v - m.mass).abs() <= 1e-12 * m.mass,
            "cell {i}: {v} vs {}",
            m.mass
        );
        if !convex {
            continue;
        }
        let c = m.centroid().unwrap();
        let size = m.mass.powf(1.0 / D as f64);
        for k in 0..D {
            let off = (q.centroid[i][k] - (sites[i][k] + c[k])).abs();
            assert!(off <= 1e-12 * size, "cell {i}: centroid off by {off:e}");
        }
    }
    let sum: f64 = q.volume.iter().sum();
    assert!((sum - total).abs() <= 1e-13 * total, "{sum} vs {total}");
}

/// `convex`: whether every face is convex (a convex domain, or any polygon: its faces are
/// edges).
fn check<const D: usize, C, K>(domain: &K, volume: f64, n: usize, convex: bool) -> MeshQuality<D>
where
    C: ConvexCell<D>,
    K: DomainKind<D> + MeshDomain<D>,
    Euclid: Space<D>,
{
    let sites = interior_sites(domain, n, 3);
    let (diagram, q) = measured::<D, C, K>(domain, &sites);
    assert_moments(convex, &diagram, &q, &sites, volume);
    q
}

#[test]
fn a_dented_cube_mesh_has_its_diagrams_cells() {
    let solid = dented_cube();
    let q = check::<3, PolyhedronCell, Boundary<3>>(&solid, solid.volume(), 300, false);
    // Random sites, no Lloyd step: the centroids are not the sites, so the bisectors are
    // not orthogonal to the centroids' segments, but never by 90 degrees or more.
    let worst = q.non_orthogonality.iter().fold(0.0f64, |m, &x| m.max(x));
    assert!(worst > 0.0 && worst < 90.0, "{worst}");
}

#[test]
fn an_octahedron_mesh_has_its_diagrams_cells_and_centroids() {
    let solid = Solid::octahedron([1.0, 0.7, 0.5]).unwrap();
    check::<3, PolyhedronCell, Boundary<3>>(&solid, solid.volume(), 300, true);
}

#[test]
fn a_square_with_a_hole_mesh_has_its_diagrams_cells() {
    let outer = [[0.0, 0.0], [2.0, 0.0], [2.0, 1.0], [0.0, 1.0]];
    let hole = [[0.5, 0.25], [0.5, 0.75], [1.5, 0.75], [1.5, 0.25]];
    let domain = polygon(&[&outer, &hole]);
    check::<2, PolygonCell, Boundary<2>>(&domain, 1.5, 200, true);
}

#[test]
fn the_bunny_mesh_has_its_diagrams_cells() {
    let Some(dir) = data_3d() else { return };
    let solid = read_mesh(&dir.join("bunny.off"));
    check::<3, PolyhedronCell, Boundary<3>>(&solid, solid.volume(), 500, false);
}
