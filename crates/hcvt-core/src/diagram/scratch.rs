//! Buffers kept per thread and reused from cell to cell: every cell of every diagram is
//! computed on some thread of the pool, and buffers made afresh for each would cost more
//! than many a cell.

use std::cell::RefCell;
use std::thread::LocalKey;

/// Run `f` with this thread's buffers of `key` (a `thread_local!` of the caller's), or with
/// fresh ones when they are taken: by a nested call from inside `f`, whose buffers the
/// inner call must not touch.
#[inline]
pub(super) fn with_scratch<T: Default, R>(
    key: &'static LocalKey<RefCell<T>>,
    f: impl FnOnce(&mut T) -> R,
) -> R {
    key.with(|cell| match cell.try_borrow_mut() {
        Ok(mut buffers) => f(&mut buffers),
        Err(_) => f(&mut T::default()),
    })
}
