// Test binaries of this crate embed CPython: link the libpython pyo3 found
// with an rpath, so they run without LD_LIBRARY_PATH. (An extension module
// built by maturin links no libpython, and this does nothing there.)
fn main() {
    pyo3_build_config::add_libpython_rpath_link_args();
}
