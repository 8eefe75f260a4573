//! # needlesim-needle
//!
//! Needle insertion (paper section 5). Written so far: the rigid needle and its pose
//! ([`needle`]), pose scripts of keyframes ([`script`]), and the segment-against-surface
//! query with a grid broad phase that the Outside state needs ([`surface_query`]). Still to
//! come (see the project's issues): the Outside / Touching / Inside state machine, node
//! addition and exact removal, stick-slip friction and the needle force.

#![warn(missing_docs)]

pub mod needle;
pub mod script;
pub mod surface_query;

pub use needle::{Needle, NeedleError};
pub use script::{Keyframe, PoseScript};
pub use surface_query::{segment_triangle, SurfaceHit, TriangleGrid};
