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
    /// Index, type and first line of the dataset in the file.
    pub location: DatasetLocation,
    /// Its typed content.
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
    Unknown {
        /// The dataset number.
        number: i64,
        /// Its lines, as read.
        text: String,
    },
}

/// Dataset 164: the file's unit system. Factors convert SI to file units:
/// `value_SI = value_file / factor`.
#[derive(Debug, Clone, PartialEq)]
pub struct Units {
    /// 1 SI, 2 BG, 3 MG, 4 BA, 5 MM, 6 CM, 7 IN, 8 GM, 9 user defined.
    pub code: i64,
    /// Unit system name as written.
    pub description: String,
    /// Temperature mode: 1 absolute, 2 relative.
    pub temperature_mode: i64,
    /// File length unit per metre.
    pub length_factor: f64,
    /// File force unit per newton.
    pub force_factor: f64,
    /// File temperature unit per kelvin.
    pub temperature_factor: f64,
    /// Temperature offset of the file unit.
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

/// A node (datasets 15 and 2411).
#[derive(Debug, Clone, PartialEq)]
pub struct Node {
    /// Node label, the number FRF datasets refer to.
    pub label: i64,
    /// Dataset 15: definition system of `coordinates`; 2411: export system (informative).
    pub definition_cs: i64,
    /// System whose axes the direction codes ±1..±3 of this node refer to.
    pub displacement_cs: i64,
    /// Display colour code (not used).
    pub color: i64,
    /// Coordinates in file length units, in the definition system.
    pub coordinates: [f64; 3],
}

/// The nodes of one dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct NodeSet {
    /// Which dataset they came from (or are to be written as).
    pub format: NodeFormat,
    /// Nodes in file order.
    pub nodes: Vec<Node>,
}

/// Kind of a coordinate system (record 1 field 2 of 2420, field 2 of 18). Only Cartesian ones can place nodes here.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CsKind {
    /// Code 0.
    Cartesian,
    /// Code 1.
    Cylindrical,
    /// Code 2.
    Spherical,
}

impl CsKind {
    /// The kind of a file code; `None` for an unknown code.
    pub fn from_code(code: i64) -> Option<Self> {
        match code {
            0 => Some(CsKind::Cartesian),
            1 => Some(CsKind::Cylindrical),
            2 => Some(CsKind::Spherical),
            _ => None,
        }
    }
    /// The file code of the kind.
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
        /// Rows 1–3: local axes in global coordinates.
        rows: [[f64; 3]; 3],
        /// Row 4: origin in global coordinates.
        origin: [f64; 3],
    },
    /// Dataset 18: origin, a point on +x and a point in the +xz half-plane, all in the
    /// reference system.
    ThreePoints {
        /// Label of the system the points are given in.
        reference_cs: i64,
        /// Method of definition as written (1: origin, +x point, +xz point).
        method: i64,
        /// Origin.
        origin: [f64; 3],
        /// A point on the +x axis.
        x_point: [f64; 3],
        /// A point in the +xz half-plane.
        xz_point: [f64; 3],
    },
}

/// A coordinate system (datasets 2420 and 18).
#[derive(Debug, Clone, PartialEq)]
pub struct CoordinateSystem {
    /// Label, the number nodes refer to.
    pub label: i64,
    /// Cartesian, cylindrical or spherical.
    pub kind: CsKind,
    /// Display colour code (not used).
    pub color: i64,
    /// Name as written (2420 only).
    pub name: String,
    /// Axes and origin.
    pub definition: CsDefinition,
}

/// The coordinate systems of one dataset.
#[derive(Debug, Clone, PartialEq)]
pub struct CoordinateSystemSet {
    /// 2420 or 18.
    pub dataset: i64,
    /// 2420 only.
    pub part_uid: Option<i64>,
    /// 2420 only.
    pub part_name: String,
    /// Systems in file order.
    pub systems: Vec<CoordinateSystem>,
}

/// Records 8–11 of dataset 58: one axis' data characteristics.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct AxisInfo {
    /// Specific data type (8 displacement, 11 velocity, 12 acceleration, 13 excitation
    /// force, 18 frequency, …).
    pub data_type: i64,
    /// Length exponent of the axis unit.
    pub length_exp: i64,
    /// Force exponent of the axis unit.
    pub force_exp: i64,
    /// Temperature exponent of the axis unit.
    pub temperature_exp: i64,
    /// Axis label ("NONE" or blank if unused).
    pub label: String,
    /// Axis units label ("NONE" or blank if unused); when given it takes precedence.
    pub units_label: String,
}

/// Record 7 field 1.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OrdinateType {
    /// Real, single precision.
    RealSingle = 2,
    /// Real, double precision.
    RealDouble = 4,
    /// Complex, single precision.
    ComplexSingle = 5,
    /// Complex, double precision.
    ComplexDouble = 6,
}

impl OrdinateType {
    /// The type of a record 7 code; `None` for an unknown code.
    pub fn from_code(code: i64) -> Option<Self> {
        match code {
            2 => Some(Self::RealSingle),
            4 => Some(Self::RealDouble),
            5 => Some(Self::ComplexSingle),
            6 => Some(Self::ComplexDouble),
            _ => None,
        }
    }
    /// Whether each value is a (re, im) pair.
    pub fn is_complex(self) -> bool {
        matches!(self, Self::ComplexSingle | Self::ComplexDouble)
    }
    /// Whether values are stored in double precision.
    pub fn is_double(self) -> bool {
        matches!(self, Self::RealDouble | Self::ComplexDouble)
    }
}

/// Binary (58b) storage details.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BinaryLayout {
    /// Byte order of the binary values.
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
    /// Record 6 field 2: function identification number.
    pub function_id: i64,
    /// Record 6 field 3: version number.
    pub version: i64,
    /// Record 6 field 4: load case.
    pub load_case: i64,
    /// Record 6 field 5: response entity name, e.g. `12X+`.
    pub response_entity: String,
    /// Record 6 field 6: response node (0 when not given).
    pub response_node: i64,
    /// ±1..±3 translations, ±4..±6 rotations, 0 scalar.
    pub response_direction: i64,
    /// Record 6 field 8: reference entity name.
    pub reference_entity: String,
    /// Record 6 field 9: reference node (0 when not given).
    pub reference_node: i64,
    /// Record 6 field 10: reference direction, coded as `response_direction`.
    pub reference_direction: i64,
    /// Record 7 field 1: real or complex, single or double precision.
    pub ordinate_type: OrdinateType,
    /// Record 7 field 3: even abscissa spacing (no abscissa values stored).
    pub even: bool,
    /// Record 7 field 4: first abscissa (frequency (Hz) for an FRF).
    pub abscissa_min: f64,
    /// Record 7 field 5: abscissa increment (used when `even`).
    pub abscissa_increment: f64,
    /// Record 7 field 6: z-axis value (not used).
    pub z_value: f64,
    /// Record 8: abscissa axis.
    pub abscissa_axis: AxisInfo,
    /// Record 9: numerator (response) axis.
    pub numerator: AxisInfo,
    /// Record 10: denominator (excitation) axis.
    pub denominator: AxisInfo,
    /// Record 11: z axis.
    pub z_axis: AxisInfo,
    /// `Some` for 58b.
    pub binary: Option<BinaryLayout>,
    /// Abscissa values (computed as `min + k·increment` for even spacing); empty for a
    /// time history held in [`Function::samples`].
    pub abscissa: Vec<f64>,
    /// Ordinate values; real data have zero imaginary parts. Empty for a time history
    /// held in [`Function::samples`].
    pub ordinate: Vec<c64>,
    /// An evenly sampled real time history (function type 1): its samples, with
    /// `abscissa` and `ordinate` left empty — a third of the memory (a recording holds
    /// millions of samples, an FRF thousands of lines). Empty for every other function.
    pub samples: Vec<f64>,
    /// The number of samples of a time history whose samples a reader has set aside
    /// (`samples` is then empty; `frf-est` keeps a recording's samples in a temporary file
    /// so that they are never all in memory); 0 otherwise.
    pub samples_set_aside: usize,
}

impl Function {
    /// Is this an evenly sampled real time history, stored in [`Function::samples`]?
    pub fn is_sampled_time_history(
        function_type: i64,
        ordinate_type: OrdinateType,
        even: bool,
    ) -> bool {
        function_type == 1 && even && !ordinate_type.is_complex()
    }

    /// The function without its data (abscissa, ordinate and samples empty): a header to
    /// build another function from without copying a record's samples.
    pub fn header(&self) -> Function {
        Function {
            id_lines: self.id_lines.clone(),
            function_type: self.function_type,
            function_id: self.function_id,
            version: self.version,
            load_case: self.load_case,
            response_entity: self.response_entity.clone(),
            response_node: self.response_node,
            response_direction: self.response_direction,
            reference_entity: self.reference_entity.clone(),
            reference_node: self.reference_node,
            reference_direction: self.reference_direction,
            ordinate_type: self.ordinate_type,
            even: self.even,
            abscissa_min: self.abscissa_min,
            abscissa_increment: self.abscissa_increment,
            z_value: self.z_value,
            abscissa_axis: self.abscissa_axis.clone(),
            numerator: self.numerator.clone(),
            denominator: self.denominator.clone(),
            z_axis: self.z_axis.clone(),
            binary: self.binary,
            abscissa: Vec::new(),
            ordinate: Vec::new(),
            samples: Vec::new(),
            samples_set_aside: 0,
        }
    }

    /// Number of points (samples or abscissa values).
    pub fn len(&self) -> usize {
        self.ordinate
            .len()
            .max(self.samples.len())
            .max(self.samples_set_aside)
    }

    /// True when the function holds no point.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The abscissa of point `k` (computed for even spacing).
    pub fn abscissa_at(&self, k: usize) -> f64 {
        match self.abscissa.get(k) {
            Some(&x) => x,
            None => self.abscissa_min + k as f64 * self.abscissa_increment,
        }
    }
}
