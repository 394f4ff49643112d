//! # exo-report
//!
//! The paper's figures and tables as exo's tools print and draw them, so
//! that every rendering is a library function any tool or test can call:
//!
//! - [`fit`]: `exo fit`'s tables (Table II and III layouts, F-tests, power
//!   law, recommended f) as text and CSV files;
//! - [`figures`]: the self-contained HTML report of `exo report` with its
//!   SVG figures (Bode plots with fits, F-test bars, power law, time
//!   responses);
//! - [`design`]: `exo design`'s Bode plot, `--json` document and summary;
//! - [`reproduction`]: `exo reproduce`'s comparison as Markdown tables;
//! - [`diagnosis`]: the HTML page of `exo diagnose` and the table of
//!   `exo diagnose-bench`.
//!
//! A crate of its own rather than a module of `exo-analysis`: the analysis
//! is shared with the identifier process, which has no use for plotters,
//! SVG or HTML; the science the tables show is computed there
//! ([`exo_analysis::study`]) and in `exo-impedance`, never here.

pub mod design;
pub mod diagnosis;
pub mod error;
pub mod figures;
pub mod fit;
pub mod reproduction;

pub use error::{Error, Result};
