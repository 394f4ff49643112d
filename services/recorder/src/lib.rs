//! exo recorder (in progress).
