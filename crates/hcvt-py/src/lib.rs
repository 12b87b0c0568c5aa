//! `hcvt._core`: the PyO3 binding of `hcvt-core`. It converts arrays and errors and
//! nothing else; every algorithm lives in the core, every user-facing check in `hcvt`.

mod arrays;
mod diagram;
mod domain;
mod errors;
mod optimise;
mod threads;

use pyo3::prelude::*;

#[pymodule]
fn _core(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<domain::PolygonDomain>()?;
    m.add_class::<domain::SolidDomain>()?;
    m.add_function(wrap_pyfunction!(diagram::voronoi_2d, m)?)?;
    m.add_function(wrap_pyfunction!(diagram::voronoi_3d, m)?)?;
    m.add_function(wrap_pyfunction!(optimise::cvt_2d, m)?)?;
    m.add_function(wrap_pyfunction!(optimise::cvt_3d, m)?)?;
    m.add_function(wrap_pyfunction!(threads::set_num_threads, m)?)?;
    m.add_function(wrap_pyfunction!(threads::get_num_threads, m)?)?;
    Ok(())
}
