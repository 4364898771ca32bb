//! The #[pymodule] behind `import pupper_core`.
