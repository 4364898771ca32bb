// Links the libpython that pyo3 was configured with (PYO3_PYTHON) and
// remembers that interpreter, so the binary finds the project's venv with
// nothing activated.
fn main() {
    pyo3_build_config::add_libpython_rpath_link_args();
    println!("cargo:rerun-if-env-changed=PYO3_PYTHON");
    if let Ok(p) = std::env::var("PYO3_PYTHON") {
        println!("cargo:rustc-env=PUPPER_BUILD_PYTHON={p}");
    }
}
