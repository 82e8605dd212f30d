//! The integration tests of rbprops-formats, one binary (`cargo nextest run -p rbprops-formats --test it`):
//! one module per topic.

mod deferred;
mod roundtrip;
