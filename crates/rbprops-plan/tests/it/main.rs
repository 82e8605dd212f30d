//! Integration tests of rbprops-plan.

mod pipeline_mc;
mod plan;
