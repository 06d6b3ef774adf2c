//! Built-in sample volumes (generated in code, no data files).
