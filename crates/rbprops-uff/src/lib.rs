//! Universal File Format (UFF, `.uff`/`.unv`) in and out for **rbprops**.
//!
//! [`parse`] reads a file's bytes into typed datasets ([`UffFile`]); [`to_campaign`]
//! turns them into an SI [`rbprops_core::Geometry`] and one [`rbprops_core::FrfSet`]; [`from_campaign`] writes a
//! campaign back. The crate does no I/O: callers pass bytes and a file name (used only in
//! error messages).
//!
//! # Datasets read
//! - **58 / 58b** function at nodal DOF: ASCII (all eight real/complex × single/double ×
//!   even/uneven cases of record 12, read with their fixed field widths) and binary 58b
//!   (IEEE 754, either byte order; abscissa and ordinate values share the ordinate's
//!   precision, as pyuff and the UC-SDRL readers store them). pyuff 2.5 announces half
//!   the byte count for complex 58b data; when the announced count is not followed by the
//!   delimiter, the count implied by record 7 is used.
//! - **15** nodes (coordinates in their definition system) and **2411** nodes (double
//!   precision, part = global coordinates).
//! - **2420** coordinate systems (rows 1–3 of the matrix are the local axes in global
//!   coordinates, row 4 the origin) and **18** coordinate systems (origin, point on +x,
//!   point in the +xz plane, in a reference system). Cartesian only: a cylindrical or
//!   spherical system is an error when a node uses it.
//! - **164** units. Any other dataset is kept as text ([`Record::Unknown`]).
//!
//! # Mapping to a campaign ([`to_campaign`])
//! - Datasets 58 with function type 4 (FRF) make the FRF set; there must be at least
//!   one (else the error lists what the file holds, [`inventory()`]). Coherence (type 6)
//!   is matched to the FRF of the same DOFs ([`CoherenceSet`]); other functions are
//!   listed in a warning.
//! - **Quantity** from record 9 (numerator) data type: 8 displacement → receptance,
//!   11 velocity → mobility, 12 acceleration → accelerance; the denominator (record 10)
//!   must be a force (13 excitation or 9 reaction). Type 0/1 (unknown/general) is
//!   accepted when the units label says what it is. All FRFs must have one quantity.
//! - **Units** are converted to SI. Dataset 164 sets the file's length and force units
//!   for the datasets after it (codes 1 SI, 2 BG, 3 MG, 4 BA, 5 MM, 6 CM, 7 IN, 8 GM: their
//!   factors must match the code's table within 1e-4; 9 user-defined: the factors are
//!   used as given). Without a 164 the file is taken as SI. An axis units label
//!   ([`units::parse_label`]) is used when it agrees in dimension with the data type;
//!   otherwise the data type with the 164 units, with a warning naming both; an error
//!   only when nothing determines the unit (precedence and grammar: `docs/formats.md`).
//!   A numerator label with the dimension of the whole FRF (`g/N`) converts the FRF alone.
//! - **DOFs** from record 6, or for node 0 / direction 0 from a channel map or the
//!   naming patterns of [`dof`] (`Point3:+Z`, …).
//! - **Geometry** from the file, or a separate file or point list ([`GeometrySource`],
//!   [`read_with_geometry`]); missing nodes are listed in the error.
//! - **Frequency axis**: abscissa type 18 (or 0) in Hz, or per its units label (`rad/s`).
//!   All FRFs must share one abscissa (within 1e-9 of its largest value); otherwise the
//!   error names both datasets.
//! - **Channels**: one per response DOF in first-appearance order, id `<node><dir>` with
//!   dir `x`, `-x`, `y`, `-y`, `z`, `-z` (`12-y` = node 12, −Y). Position = node
//!   coordinates; direction = ± axis 1..3 of the node's displacement coordinate system
//!   (the global axes for system 0). Scalar and rotational DOFs are errors.
//! - **Excitations**: one per (reference DOF, set-up), id `<node><dir>` in set-up `A`
//!   and `<node><dir>@<setup>` in other set-ups.
//! - **Set-ups**: from ID line 4 of each dataset 58 when it reads `setup=<id>
//!   [description]`; otherwise [`DEFAULT_SETUP`] (`A`).
//! - **Points**: one per node (datasets 15/2411, file order), id = node label.
//! - **Tags**: when ID line 5 reads `rbprops ch=<channel id> cp=<point id> ex=<excitation
//!   id> ep=<point id>`, those ids replace the defaults (this is how our own files keep
//!   their names; nodes that share a point id become one point).
//! - Every (excitation, channel) pair must have exactly one FRF; a missing or doubled
//!   pair is an error naming it. A node referenced by a dataset 58 without coordinates is
//!   an error naming the dataset and field.
//!
//! # Writing ([`from_campaign`])
//! Dataset 164 (SI), 2420 (only if some direction is not ±X/±Y/±Z), 2411 (default) or 15
//! nodes, then one dataset 58 per (excitation, channel) in excitation-major order,
//! complex double (ordinate type 6). Node labels are the point ids when all are positive
//! integers, else 1, 2, …; a point whose directions are not mutually orthogonal gets
//! extra nodes at the same place, each with its own displacement system whose axes are
//! the directions themselves, so directions round-trip bit-exactly. ID line 1 is a
//! readable description, ID line 4 `setup=<id> <description>`, ID line 5 the tags above
//! (omitted when an id contains blanks or '=' or the line would exceed 80 characters).
//! Not carried: set-ups no excitation uses, and the ids of points no channel or excitation
//! uses unless every point id is a positive integer (they come back as node labels).
//!
//! # Precision of a round trip
//! - ASCII 58: values in 20-column `E` fields with 13 significant digits (relative error
//!   ≤ 5e-13 per component). Frequencies: record 7 and the uneven abscissa are 13-column
//!   fields; a value whose shortest exact decimal form fits in 12 characters (e.g.
//!   `0.0125`) is written exactly, others with as many digits as fit (at least 7
//!   significant digits). Even spacing is used when the written start
//!   and step reproduce the axis to 1e-12.
//! - Binary 58b: bit-exact (uneven spacing with double abscissae unless the even header
//!   reproduces the axis bit for bit).
//! - 2411 nodes and 2420 systems: 17 significant digits (exact). Dataset 15: 12-column
//!   fields as above.
//!
//! # Independent checks (pyuff)
//! `scripts/make_uff_fixtures.py` writes `fixtures/uff/*.uff` with pyuff and JSON sidecars
//! of the exact values; `tests/it/pyuff_fixtures.rs` reads them to the printed precision.
//! `scripts/make_uff_exports.py` writes `fixtures/uff/exports/`: pyuff files edited the
//! way analysers write them (labels, CRLF, node 0, split geometry, coherence, no FRF);
//! `tests/it/exports.rs` reads each to the SI values the script computed by hand, or checks
//! the error.
//! The test `tests/it/written_for_pyuff.rs` writes `fixtures/uff/written/rbprops_{ascii,binary}
//! .{uff,json}`; CI then runs, for both,
//! `python3 scripts/check_uff_with_pyuff.py fixtures/uff/written/rbprops_ascii.uff
//! fixtures/uff/written/rbprops_ascii.json` (exit status 1 on any mismatch).

#![warn(missing_docs)]

pub mod averages;
pub mod campaign;
pub mod dof;
pub mod error;
pub mod fortran;
pub mod inventory;
pub mod model;
pub mod read;
pub mod timehist;
pub mod timerec;
pub mod units;
pub mod write;

pub use averages::{declared_averages, DeclaredAverages};
pub use campaign::{
    dof_name, read_campaign, read_with_geometry, to_campaign, CoherenceSet, GeometrySource,
    ReadOptions, UffCampaign, DEFAULT_SETUP,
};
pub use dof::{channel_map_template, ChannelMap};
pub use error::{DatasetLocation, UffError};
pub use inventory::inventory;
pub use model::*;
pub use read::{parse, parse_reader, parse_reader_each};
pub use write::{from_campaign, WriteOptions};
