//! Whitespace-separated numeric rows, as the profiling examples read their meshes and sites.

/// Reads `path` as rows of `N` numbers each (blank lines skipped); panics naming the file and
/// the bad token, since an example has no caller to return an error to.
pub fn read_rows<T: std::str::FromStr, const N: usize>(path: &str) -> Vec<[T; N]> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(|l| {
            let mut it = l.split_whitespace().map(|x| {
                x.parse::<T>()
                    .unwrap_or_else(|_| panic!("{path}: bad number {x}"))
            });
            std::array::from_fn(|_| it.next().expect("short row"))
        })
        .collect()
}
