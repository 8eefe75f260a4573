//! # needlesim-needle
//!
//! Needle insertion (paper section 5): the Outside / Touching / Inside state machine, node
//! addition and exact removal, stick-slip friction and the needle force, driving any
//! `needlesim_core::Backend`. Not written yet: this crate reserves its place in the
//! workspace and exports nothing.
