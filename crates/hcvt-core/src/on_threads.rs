//! Tests only: run a computation on a pool of a given number of threads, to check that a
//! result does not depend on the thread count (DESIGN: deterministic for any number of
//! threads).

/// `f()` run on a fresh rayon pool of `threads` threads.
pub(crate) fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .expect("a thread pool for the test")
        .install(f)
}
