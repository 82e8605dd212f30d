//! Typed UFF datasets, as they are in the file (file units, file node numbers).
//! [`crate::to_campaign`] turns them into SI geometry and FRFs.

use crate::error::DatasetLocation;
use rbprops_core::c64;

/// A parsed universal file.
#[derive(Debug, Clone, PartialEq)]
pub struct UffFile {
    /// The name the caller gave [`crate::parse`], used in every error message.
    pub file_name: String,
    /// Datasets in file order.
    pub datasets: Vec<Dataset>,
}

/// One dataset and where it sits in the file.
#[derive(Debug, Clone, PartialEq)]
pub struct Dataset {
    pub location: DatasetLocation,
    pub record: Record,
}

/// The typed content of a dataset.
#[derive(Debug, Clone, PartialEq)]
pub enum Record {
    /// Dataset 164.
    Units(Units),
    /// Dataset 15 or 2411.
    Nodes(NodeSet),
    /// Dataset 2420 or 18.
    CoordinateSystems(CoordinateSystemSet),
    /// Dataset 58 (ASCII) or 58b (binary).
    Function(Box<Function>),
    /// Any other dataset, kept as its (lossily decoded) text lines.
    Unknown { number: i64, text: String },
}

/// Dataset 164: the file's unit system. Factors convert SI to file units:
/// `value_SI = value_file / factor`.
#[derive(Debug, Clone, PartialEq)]
pub struct Units {
    /// 1 SI, 2 BG, 3 MG, 4 BA, 5 MM, 6 CM, 7 IN, 8 GM, 9 user defined.
    pub code: i64,
    pub description: String,
    pub temperature_mode: i64,
    pub length_factor: f64,
    pub force_factor: f64,
    pub temperature_factor: f64,
    pub temperature_offset: f64,
}

/// Which dataset the nodes came from (or are to be written as).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeFormat {
    /// Dataset 15, single precision `E13.5` coordinates in the definition system.
    D15,
    /// Dataset 2411, double precision `D25.16` coordinates in the part (global) system.
    D2411,
}

#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    pub label: i64,
    /// Dataset 15: definition system of `coordinates`; 2411: export system (informative).
    pub definition_cs: i64,
    /// System whose axes the direction codes ±1..±3 of this node refer to.
    pub displacement_cs: i64,
    pub color: i64,
    pub coordinates: [f64; 3],
}

#[derive(Debug, Clone, PartialEq)]
pub struct NodeSet {
    pub format: NodeFormat,
    pub nodes: Vec<Node>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CsKind {
    Cartesian,
    Cylindrical,
    Spherical,
}

impl CsKind {
    pub fn from_code(code: i64) -> Option<Self> {
        match code {
            0 => Some(CsKind::Cartesian),
            1 => Some(CsKind::Cylindrical),
            2 => Some(CsKind::Spherical),
            _ => None,
        }
    }
    pub fn code(self) -> i64 {
        match self {
            CsKind::Cartesian => 0,
            CsKind::Cylindrical => 1,
            CsKind::Spherical => 2,
        }
    }
}

/// How a coordinate system is given.
#[derive(Debug, Clone, PartialEq)]
pub enum CsDefinition {
    /// Dataset 2420: rows 1–3 are the local x, y, z axes in global coordinates
    /// (`global = Rᵀ local + origin`), row 4 the origin.
    Matrix {
        rows: [[f64; 3]; 3],
        origin: [f64; 3],
    },
    /// Dataset 18: origin, a point on +x and a point in the +xz half-plane, all in the
    /// reference system.
    ThreePoints {
        reference_cs: i64,
        method: i64,
        origin: [f64; 3],
        x_point: [f64; 3],
        xz_point: [f64; 3],
    },
}

#[derive(Debug, Clone, PartialEq)]
pub struct CoordinateSystem {
    pub label: i64,
    pub kind: CsKind,
    pub color: i64,
    pub name: String,
    pub definition: CsDefinition,
}

#[derive(Debug, Clone, PartialEq)]
pub struct CoordinateSystemSet {
    /// 2420 or 18.
    pub dataset: i64,
    /// 2420 only.
    pub part_uid: Option<i64>,
    /// 2420 only.
    pub part_name: String,
    pub systems: Vec<CoordinateSystem>,
}

/// Records 8–11 of dataset 58: one axis' data characteristics.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AxisInfo {
    /// Specific data type (8 displacement, 11 velocity, 12 acceleration, 13 excitation
    /// force, 18 frequency, …).
    pub data_type: i64,
    pub length_exp: i64,
    pub force_exp: i64,
    pub temperature_exp: i64,
    /// Axis label ("NONE" or blank if unused).
    pub label: String,
    /// Axis units label ("NONE" or blank if unused); when given it takes precedence.
    pub units_label: String,
}

/// Record 7 field 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrdinateType {
    RealSingle = 2,
    RealDouble = 4,
    ComplexSingle = 5,
    ComplexDouble = 6,
}

impl OrdinateType {
    pub fn from_code(code: i64) -> Option<Self> {
        match code {
            2 => Some(Self::RealSingle),
            4 => Some(Self::RealDouble),
            5 => Some(Self::ComplexSingle),
            6 => Some(Self::ComplexDouble),
            _ => None,
        }
    }
    pub fn is_complex(self) -> bool {
        matches!(self, Self::ComplexSingle | Self::ComplexDouble)
    }
    pub fn is_double(self) -> bool {
        matches!(self, Self::RealDouble | Self::ComplexDouble)
    }
}

/// Binary (58b) storage details.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BinaryLayout {
    pub little_endian: bool,
}

/// Dataset 58: a function at a nodal DOF (here: an FRF between a response and a
/// reference DOF).
#[derive(Debug, Clone, PartialEq)]
pub struct Function {
    /// ID lines 1–5 (trailing blanks removed).
    pub id_lines: [String; 5],
    /// Record 6 field 1: 4 = frequency response function.
    pub function_type: i64,
    pub function_id: i64,
    pub version: i64,
    pub load_case: i64,
    pub response_entity: String,
    pub response_node: i64,
    /// ±1..±3 translations, ±4..±6 rotations, 0 scalar.
    pub response_direction: i64,
    pub reference_entity: String,
    pub reference_node: i64,
    pub reference_direction: i64,
    pub ordinate_type: OrdinateType,
    /// Record 7 field 3: even abscissa spacing (no abscissa values stored).
    pub even: bool,
    pub abscissa_min: f64,
    pub abscissa_increment: f64,
    pub z_value: f64,
    pub abscissa_axis: AxisInfo,
    pub numerator: AxisInfo,
    pub denominator: AxisInfo,
    pub z_axis: AxisInfo,
    /// `Some` for 58b.
    pub binary: Option<BinaryLayout>,
    /// Abscissa values (computed as `min + k·increment` for even spacing).
    pub abscissa: Vec<f64>,
    /// Ordinate values; real data have zero imaginary parts.
    pub ordinate: Vec<c64>,
}
