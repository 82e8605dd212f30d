//! Integration tests of rbprops-plan.

#![allow(clippy::needless_range_loop)] // index loops over the ten properties

mod pipeline_mc;
mod plan;
