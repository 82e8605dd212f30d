//! The integration tests of rbprops-plot, one binary (`cargo nextest run -p rbprops-plot --test it`):
//! one module per topic, shared fixtures in `common`.

mod common;
mod compact;
mod layout;
mod line_plot;
mod no_fonts;
mod other_kinds;
mod shading;
