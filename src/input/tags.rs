//! Simple 3D Buildings tags, parsed leniently (`12 m`, `12;15`, `12,5`, `40'`).

use crate::color::Color;
use crate::model::RoofShape;

/// The building tags citygen honours. `None` when absent or unusable; every unusable value is
/// listed in `ignored` as `(key, value, reason)` for the report.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct BuildingTags {
    /// `building=*` or `building:part=*` value (e.g. `yes`, `house`, `apartments`).
    pub building: Option<String>,
    pub name: Option<String>,
    /// `height` in metres, total height including the roof.
    pub height: Option<f64>,
    /// `min_height` in metres.
    pub min_height: Option<f64>,
    /// `building:levels` (above ground, without roof levels).
    pub levels: Option<f64>,
    /// `building:min_level`.
    pub min_level: Option<f64>,
    pub roof_shape: Option<RoofShape>,
    /// `roof:height` in metres.
    pub roof_height: Option<f64>,
    /// `roof:angle` in degrees.
    pub roof_angle: Option<f64>,
    /// `roof:levels`.
    pub roof_levels: Option<f64>,
    /// `roof:orientation` = along / across.
    pub roof_orientation: Option<String>,
    /// `roof:direction` in degrees from north (cardinal letters accepted).
    pub roof_direction: Option<f64>,
    pub colour: Option<Color>,
    pub roof_colour: Option<Color>,
    pub material: Option<String>,
    pub roof_material: Option<String>,
    /// Values that were present but could not be used: (key, value, reason).
    pub ignored: Vec<(String, String, String)>,
}

impl BuildingTags {
    /// Builds the parsed tags from raw key/value pairs (OSM tags or shapefile attributes mapped
    /// to OSM keys). Unknown keys are ignored silently; known keys with bad values go to `ignored`.
    pub fn from_pairs<'a>(pairs: impl IntoIterator<Item = (&'a str, &'a str)>) -> BuildingTags {
        todo!("tags::from_pairs {:?}", pairs.into_iter().count())
    }
}

/// Parses a length in metres leniently: `12`, `12 m`, `12m`, `12,5`, `12;15` (first value),
/// `40'` or `40 ft` (feet), `12'6"`. Rejects NaN, infinities and negative values.
pub fn parse_length(s: &str) -> Option<f64> {
    todo!("parse_length {s}")
}
