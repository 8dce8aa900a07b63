//! Tetrahedral meshes: the in-memory form, readers, validation and surface extraction.
