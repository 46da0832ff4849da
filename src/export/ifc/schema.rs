//! The IFC schemas the writer can write (`--ifc-schema`) and, in one place, what differs
//! between them: entity names and the attributes a schema has or lacks. The writer writes
//! IFC4 and asks here wherever another schema differs; an IFC4 file is the same bytes as
//! before the choice existed.
//!
//! | | IFC2X3 | IFC4 | IFC4X3_ADD2 |
//! |---|---|---|---|
//! | `OwnerHistory` of rooted entities | an `IfcOwnerHistory` (mandatory) | `$` | `$` |
//! | georeferencing | `IfcSite` RefLatitude/RefLongitude/RefElevation | + `IfcMapConversion`, `IfcProjectedCRS` | same as IFC4 |
//! | walls | `IfcWallStandardCase` (no PredefinedType) | `IfcWallStandardCase` | `IfcWall` |
//! | window/door types | `IfcWindowStyle`/`IfcDoorStyle`, no `IfcRelDeclares` | `IfcWindowType`/`IfcDoorType` | same as IFC4 |
//! | `IfcStyledItem.Styles` | through an `IfcPresentationStyleAssignment` | the surface style | same as IFC4 |
//! | terrain | `IfcBuildingElementProxy`, an `IfcShellBasedSurfaceModel` of triangles | `IfcGeographicElement` `.TERRAIN.`, `IfcTriangulatedFaceSet` | same as IFC4 |
//! | `IfcSpace` | InteriorOrExteriorSpace `.INTERNAL.` | PredefinedType `.SPACE.` | same as IFC4 |
//! | window, door and opening bodies | items shared, a representation and product shape per product | one product shape shared | same as IFC4 |
//! | optional `Position` of swept solids | mandatory: the identity placement | `$` | `$` |
//!
//! Attributes IFC4 appended to an IFC2X3 entity (`Formula` of quantities, a material's
//! `Description`/`Category`, PredefinedType of openings, walls, windows and doors, ...) are
//! left out in IFC2X3 ([`IfcSchema::ifc4_attributes`]); `IfcCartesianPointList3D` gains
//! IFC4X3's `TagList` (`$`).

use std::fmt;
use std::str::FromStr;

/// An IFC schema the writer can write.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum IfcSchema {
    /// IFC2X3 TC1 (Coordination View 2.0's schema), for tools that read nothing newer.
    Ifc2x3,
    /// IFC4 ADD2 TC1, the default.
    #[default]
    Ifc4,
    /// IFC4.3 ADD2 (ISO 16739-1:2024).
    Ifc4x3Add2,
}

/// A `--ifc-schema` value that names no schema the writer knows.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct UnknownSchema(pub String);

impl fmt::Display for UnknownSchema {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown IFC schema {:?}: expected IFC2X3, IFC4 or IFC4X3_ADD2",
            self.0
        )
    }
}

impl std::error::Error for UnknownSchema {}

impl FromStr for IfcSchema {
    type Err = UnknownSchema;

    /// `IFC2X3`, `IFC4` or `IFC4X3_ADD2`, in any case (`IFC4X3` is taken for `IFC4X3_ADD2`).
    fn from_str(s: &str) -> Result<IfcSchema, UnknownSchema> {
        match s.trim().to_ascii_uppercase().as_str() {
            "IFC2X3" => Ok(IfcSchema::Ifc2x3),
            "IFC4" => Ok(IfcSchema::Ifc4),
            "IFC4X3" | "IFC4X3_ADD2" => Ok(IfcSchema::Ifc4x3Add2),
            _ => Err(UnknownSchema(s.to_string())),
        }
    }
}

impl fmt::Display for IfcSchema {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl IfcSchema {
    /// The schema's name in the header's FILE_SCHEMA.
    pub fn name(self) -> &'static str {
        match self {
            IfcSchema::Ifc2x3 => "IFC2X3",
            IfcSchema::Ifc4 => "IFC4",
            IfcSchema::Ifc4x3Add2 => "IFC4X3_ADD2",
        }
    }

    /// The header's FILE_DESCRIPTION view definition.
    pub(super) fn view_definition(self) -> &'static str {
        match self {
            IfcSchema::Ifc2x3 => "ViewDefinition [CoordinationView_V2.0]",
            IfcSchema::Ifc4 | IfcSchema::Ifc4x3Add2 => "ViewDefinition [DesignTransferView_V1.0]",
        }
    }

    /// Whether rooted entities need an `IfcOwnerHistory` (IFC2X3).
    pub(super) fn owner_history(self) -> bool {
        self == IfcSchema::Ifc2x3
    }

    /// Whether the schema has the attributes IFC4 added at the end of IFC2X3 entities, and
    /// IFC4's entities (`IfcMapConversion`, `IfcProjectedCRS`, `IfcTriangulatedFaceSet`,
    /// `IfcGeographicElement`, `IfcRelDeclares`, window and door types).
    pub(super) fn ifc4_attributes(self) -> bool {
        self != IfcSchema::Ifc2x3
    }

    /// Whether a swept solid's or profile's `Position` is mandatory (IFC2X3).
    pub(super) fn position_mandatory(self) -> bool {
        self == IfcSchema::Ifc2x3
    }

    /// Whether several products may share one `IfcProductDefinitionShape` (not in IFC2X3,
    /// whose `ShapeOfProduct` and `OfProductRepresentation` are `SET [0:1]`).
    pub(super) fn shared_shapes(self) -> bool {
        self != IfcSchema::Ifc2x3
    }

    /// Whether `IfcStyledItem.Styles` holds `IfcPresentationStyleAssignment`s (IFC2X3).
    pub(super) fn style_assignments(self) -> bool {
        self == IfcSchema::Ifc2x3
    }

    /// The wall entity: `IfcWallStandardCase`, deprecated in IFC4X3 (`IfcWall` there).
    pub(super) fn wall(self) -> &'static str {
        match self {
            IfcSchema::Ifc4x3Add2 => "IFCWALL",
            IfcSchema::Ifc2x3 | IfcSchema::Ifc4 => "IFCWALLSTANDARDCASE",
        }
    }

    /// The entity of a window (`door` false) or door type: IFC2X3's styles, IFC4's types.
    pub(super) fn fill_type(self, door: bool) -> &'static str {
        match (self.ifc4_attributes(), door) {
            (true, true) => "IFCDOORTYPE",
            (true, false) => "IFCWINDOWTYPE",
            (false, true) => "IFCDOORSTYLE",
            (false, false) => "IFCWINDOWSTYLE",
        }
    }

    /// The terrain's entity: IFC2X3 has no `IfcGeographicElement`.
    pub(super) fn terrain(self) -> &'static str {
        if self.ifc4_attributes() {
            "IFCGEOGRAPHICELEMENT"
        } else {
            "IFCBUILDINGELEMENTPROXY"
        }
    }

    /// Whether `IfcCartesianPointList3D` ends with IFC4X3's `TagList`.
    pub(super) fn point_list_tags(self) -> bool {
        self == IfcSchema::Ifc4x3Add2
    }

    /// How many of the trailing `IfcWindowLiningProperties` (`door` false) or
    /// `IfcDoorLiningProperties` attributes after LiningThickness the schema has (all `$` in
    /// the writer's use): IFC4 appended LiningOffset and LiningToPanelOffsetX/Y to windows
    /// and LiningToPanelOffsetX/Y to doors.
    pub(super) fn lining_tail(self, door: bool) -> usize {
        match (self.ifc4_attributes(), door) {
            (true, true) => 11,
            (true, false) => 10,
            (false, true) => 9,
            (false, false) => 7,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_names_parse_back_and_unknown_ones_are_refused() {
        for s in [IfcSchema::Ifc2x3, IfcSchema::Ifc4, IfcSchema::Ifc4x3Add2] {
            assert_eq!(s.name().parse::<IfcSchema>(), Ok(s));
            assert_eq!(s.name().to_lowercase().parse::<IfcSchema>(), Ok(s));
        }
        assert_eq!("ifc4x3".parse::<IfcSchema>(), Ok(IfcSchema::Ifc4x3Add2));
        let e = "IFC5".parse::<IfcSchema>().unwrap_err();
        assert!(e.to_string().contains("IFC2X3, IFC4 or IFC4X3_ADD2"), "{e}");
        assert_eq!(IfcSchema::default(), IfcSchema::Ifc4);
    }

    #[test]
    fn each_schema_gets_entities_it_has() {
        use IfcSchema::*;
        assert_eq!(Ifc4.wall(), "IFCWALLSTANDARDCASE");
        assert_eq!(Ifc2x3.wall(), "IFCWALLSTANDARDCASE");
        assert_eq!(Ifc4x3Add2.wall(), "IFCWALL");
        assert_eq!(Ifc2x3.fill_type(true), "IFCDOORSTYLE");
        assert_eq!(Ifc2x3.fill_type(false), "IFCWINDOWSTYLE");
        assert_eq!(Ifc4.fill_type(true), "IFCDOORTYPE");
        assert_eq!(Ifc4x3Add2.fill_type(false), "IFCWINDOWTYPE");
        assert_eq!(Ifc2x3.terrain(), "IFCBUILDINGELEMENTPROXY");
        assert_eq!(Ifc4.terrain(), "IFCGEOGRAPHICELEMENT");
        assert!(Ifc2x3.owner_history() && !Ifc4.owner_history() && !Ifc4x3Add2.owner_history());
        assert!(Ifc2x3.position_mandatory() && !Ifc4.position_mandatory());
        assert!(Ifc2x3.style_assignments() && !Ifc4x3Add2.style_assignments());
        assert!(Ifc4x3Add2.point_list_tags() && !Ifc4.point_list_tags());
        assert!(!Ifc2x3.shared_shapes() && Ifc4.shared_shapes() && Ifc4x3Add2.shared_shapes());
        // IfcDoorLiningProperties: 17 attributes in IFC4, 15 in IFC2X3; windows 16 and 13.
        assert_eq!(6 + Ifc4.lining_tail(true), 17);
        assert_eq!(6 + Ifc2x3.lining_tail(true), 15);
        assert_eq!(6 + Ifc4.lining_tail(false), 16);
        assert_eq!(6 + Ifc2x3.lining_tail(false), 13);
    }
}
