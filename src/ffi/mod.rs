//! The C API (see `include/precisemc.h`).
