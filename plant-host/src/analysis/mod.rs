//! Linear analysis (nalgebra).
