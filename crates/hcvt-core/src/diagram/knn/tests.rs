use super::*;

fn random_points<const D: usize>(n: usize, seed: u64) -> Vec<[f64; D]> {
    let mut rng = crate::sample::Lcg::new(seed);
    (0..n)
        .map(|_| std::array::from_fn(|_| rng.unit()))
        .collect()
}

/// Every site, by squared distance then index, as the grid streams them.
fn brute_force<const D: usize>(sites: &[[f64; D]], p: [f64; D]) -> Vec<(u32, f64)> {
    let mut all: Vec<(u32, f64)> = (0..sites.len())
        .map(|j| (j as u32, norm2(sub(sites[j], p))))
        .collect();
    all.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    all
}

fn streamed<const D: usize>(index: &SiteIndex<D>, p: [f64; D]) -> Vec<(u32, f64)> {
    index.nearest(p, usize::MAX)
}

/// Sites so far apart that their squared coordinates overflow (hypothesis found it:
/// the slack became infinite, the bound NaN, and the rings grew for ever).
#[test]
fn sites_whose_squares_overflow_stream_to_the_end() {
    let sites = [
        [2.8794063704950784e18, 0.0],
        [5.549490502643398e-160, -1.7478835447777867e185],
        [5e-324, 0.0],
        [0.0, 0.0],
        [5e-324, -4.802692022558717e-206],
    ];
    let index = SiteIndex::new(&sites).unwrap();
    for &p in &sites {
        // The stream ends; a site at an infinite squared distance is beyond any limit.
        let finite: Vec<_> = brute_force(&sites, p)
            .into_iter()
            .filter(|s| s.1.is_finite())
            .collect();
        assert_eq!(streamed(&index, p), finite, "query {p:?}");
        assert_eq!(index.nearest_one(p), finite[0], "query {p:?}");
    }
}

fn assert_streams_in_order<const D: usize>(sites: &[[f64; D]], queries: &[[f64; D]]) {
    let index = SiteIndex::new(sites).unwrap();
    assert!(matches!(index.kind, Kind::Grid(_)));
    for &p in queries {
        let expected = brute_force(sites, p);
        assert_eq!(streamed(&index, p), expected, "query {p:?}");
        assert_eq!(index.nearest_one(p), expected[0], "query {p:?}");
    }
}

#[test]
fn the_grid_streams_every_site_in_order_of_distance() {
    let sites = random_points::<2>(500, 1);
    let mut queries = random_points::<2>(20, 2);
    // Far outside the sites' box, and on sites (as the diagram asks).
    queries.extend([[-3.0, 0.5], [7.0, 9.0], [0.5, -1e3], sites[3], sites[77]]);
    assert_streams_in_order(&sites, &queries);
    let sites3 = random_points::<3>(400, 3);
    assert_streams_in_order(&sites3, &[sites3[0], [2.0, -1.0, 0.5], [0.5; 3]]);
}

#[test]
fn sites_filling_part_of_their_box_get_finer_buckets_and_stream_in_order() {
    // Sites in the lower-left triangle of the unit square (and one corner site that
    // spans the box): half of the coarse buckets would be empty.
    let mut sites: Vec<[f64; 2]> = random_points::<2>(2000, 9)
        .into_iter()
        .filter(|p| p[0] + p[1] < 0.8)
        .collect();
    sites.push([1.0, 1.0]);
    let index = SiteIndex::new(&sites).unwrap();
    let Kind::Grid(grid) = &index.kind else {
        panic!("a grid")
    };
    let buckets = grid.buckets.len();
    assert!(
        buckets > sites.len(),
        "{buckets} buckets for {} sites",
        sites.len()
    );
    assert_streams_in_order(&sites, &[sites[0], sites[100], [0.9, 0.9], [0.1, 0.7]]);
}

#[test]
fn flat_and_single_site_grids_stream_in_order() {
    let line: Vec<[f64; 2]> = (0..50).map(|k| [k as f64 * 0.37, 2.0]).collect();
    assert_streams_in_order(&line, &[[3.0, 2.0], [-1.0, 5.0], [100.0, 2.0]]);
    assert_streams_in_order(&[[1.0, 1.0]], &[[1.0, 1.0], [5.0, -3.0]]);
    // Ties: a square lattice seen from its centres.
    let lattice: Vec<[f64; 2]> = (0..100)
        .map(|k| [(k % 10) as f64, (k / 10) as f64])
        .collect();
    assert_streams_in_order(&lattice, &[[4.5, 4.5], [0.0, 0.0], [3.0, 7.5]]);
}

#[test]
fn a_limit_stops_the_stream_before_farther_sites() {
    let sites = random_points::<2>(300, 5);
    let index = SiteIndex::new(&sites).unwrap();
    let mut scratch = NearScratch::default();
    let mut near = index.near(sites[0], &mut scratch);
    let expected = brute_force(&sites, sites[0]);
    let limit2 = expected[9].1;
    let got: Vec<_> = std::iter::from_fn(|| near.next_within(limit2)).collect();
    assert_eq!(got, expected[..10]);
    assert_eq!(near.next_within(limit2), None);
}

/// A deferred grid is not filled while a warm stream answers from its candidates;
/// asked beyond them, the stream fills it and goes on as the cold stream does.
#[test]
fn a_warm_stream_fills_a_deferred_grid_only_when_it_goes_cold() {
    let sites = random_points::<2>(2000, 13);
    let deferred = DeferredIndex::new(&sites).unwrap();
    let i = 77;
    let p = sites[i];
    let cold = brute_force(&sites, p);
    // Candidates: the 12 nearest sites (shuffled), complete within the 12th distance.
    let mut candidates: Vec<u32> = cold[..12].iter().map(|&(j, _)| j).rev().collect();
    candidates.swap(3, 8);
    let certified2 = cold[11].1;
    let mut scratch = NearScratch::default();
    let index = IndexRef::from(&deferred);
    let mut near = index.near_warm(p, &sites, &candidates, certified2, &mut scratch);
    let mut got = Vec::new();
    while let Some(next) = near.next_within(certified2) {
        got.push(next);
    }
    assert_eq!(got, cold[..12]);
    assert!(deferred.index.get().is_none(), "filled by a warm stream");
    while let Some(next) = near.next_within(f64::INFINITY) {
        got.push(next);
    }
    assert!(deferred.index.get().is_some());
    assert_eq!(got, cold);
}

#[test]
fn warm_lists_sort_as_sort_unstable_does_however_shuffled() {
    let mut rng = crate::sample::Lcg::new(11);
    for len in [0, 1, 2, 7, 30, 64, 65, 200] {
        let sorted: Vec<(u64, u32)> = (0..len)
            .map(|j| ((rng.unit() * 100.0).floor().to_bits(), j as u32))
            .collect();
        let mut sorted = sorted;
        sorted.sort_unstable();
        // Nearly sorted (neighbours swapped), reversed, and shuffled.
        let mut nearly = sorted.clone();
        for k in (1..len).step_by(3) {
            nearly.swap(k - 1, k);
        }
        let reversed: Vec<_> = sorted.iter().rev().copied().collect();
        let mut shuffled = sorted.clone();
        for k in (1..len).rev() {
            shuffled.swap(k, (rng.unit() * (k + 1) as f64) as usize);
        }
        for mut list in [nearly, reversed, shuffled] {
            sort_nearly_sorted(&mut list);
            assert_eq!(list, sorted, "length {len}");
        }
    }
}

#[test]
fn clustered_sites_fall_back_to_the_kd_tree() {
    // All sites but one in a tiny region: one bucket would hold nearly all of them.
    let mut sites: Vec<[f64; 2]> = random_points::<2>(400, 7)
        .into_iter()
        .map(|p| [p[0] * 1e-6, p[1] * 1e-6])
        .collect();
    sites.push([1e3, 1e3]);
    let index = SiteIndex::new(&sites).unwrap();
    assert!(matches!(index.kind, Kind::Tree(..)));
    for p in [sites[5], sites[400], [0.5, 0.5]] {
        let got = streamed(&index, p);
        let expected = brute_force(&sites, p);
        assert_eq!(got.len(), expected.len());
        let dists = |v: &[(u32, f64)]| v.iter().map(|x| x.1).collect::<Vec<_>>();
        assert_eq!(dists(&got), dists(&expected));
    }
}
