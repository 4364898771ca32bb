"""A module per kind of run: its function, which `pupper_core._run` re-exports
(one line there per kind)."""
