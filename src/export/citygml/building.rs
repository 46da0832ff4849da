//! The building element of the CityGML writer: `bldg:Building` with its envelope, attributes and
//! parts (`bldg:BuildingPart`), and the ids derived from the source id.

use crate::export::ids::{id_fragment, part_ids};
use crate::export::lod3geom::{balcony_faces, cornice_solids, eaves_solids, wall_sill_faces};
use crate::model::{AttrValue, Attributes, Building, Provenance, RoofShape};

use super::surfaces::{surfaces, written_walls};
use super::{GeometryLod, Renderer, ROOF_TYPE_CODESPACE};

impl Renderer<'_> {
    pub(super) fn building(&mut self, b: &Building) {
        let id = format!("B_{}", id_fragment(&b.key()));
        let parts = part_ids(&id, &b.parts);
        let x = &mut *self.x;
        x.s("<core:cityObjectMember>\n<bldg:Building gml:id=\"");
        x.s(&id);
        x.s("\">\n");
        if let Some(name) = &b.name {
            x.s("<gml:name>");
            x.escaped(name, false);
            x.s("</gml:name>\n");
        }
        self.envelope(b);
        self.string_attribute("sourceId", &b.id.to_string());
        if !b.zone.is_empty() {
            self.string_attribute("zone", &b.zone);
        }
        if !b.appearance.is_empty() {
            self.string_attribute("appearance", &b.appearance);
        }
        self.provenance(&b.provenance);
        if let Some(a) = &b.attributes {
            self.input_attributes(a);
        }
        if let [part] = b.parts.as_slice() {
            if let Some(source) = part.traced_source(b.id) {
                self.string_attribute("partSourceId", &source.to_string());
            }
            if let Some(class) = part.structure {
                self.string_attribute("structure", class.name());
            }
        }
        self.appearance(&id, b, &parts);
        self.building_attributes(b.roof_shape, b.measured_height, b.storeys_above_ground);
        match b.parts.as_slice() {
            [part] => self.geometry(part, &parts[0]),
            _ => {
                for (part, pid) in b.parts.iter().zip(&parts) {
                    let x = &mut *self.x;
                    x.s("<bldg:consistsOfBuildingPart>\n<bldg:BuildingPart gml:id=\"");
                    x.s(pid);
                    x.s("\">\n");
                    if let Some(source) = part.traced_source(b.id) {
                        self.string_attribute("sourceId", &source.to_string());
                    }
                    if let Some(role) = part.role.name() {
                        self.string_attribute("sourceRole", role);
                    }
                    if let Some(class) = part.structure {
                        self.string_attribute("structure", class.name());
                    }
                    // Its top above the building's ground, as the building's own.
                    self.building_attributes(
                        part.roof_shape,
                        part.height_above(b.ground_z),
                        part.storeys,
                    );
                    self.geometry(part, pid);
                    self.x
                        .s("</bldg:BuildingPart>\n</bldg:consistsOfBuildingPart>\n");
                }
            }
        }
        self.x.s("</bldg:Building>\n</core:cityObjectMember>\n");
    }

    /// `gml:boundedBy` of the building's written polygons; nothing when it has none.
    fn envelope(&mut self, b: &Building) {
        let mut points = b
            .parts
            .iter()
            .flat_map(|p| surfaces(p).flat_map(|s| s.face.outer.iter()));
        let Some(&first) = points.next() else {
            return;
        };
        let (mut lo, mut hi) = points.fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
        if self.lod >= GeometryLod::Lod3 {
            // Balconies and window sills stand out of the walls.
            for part in &b.parts {
                for (_, wall) in written_walls(part) {
                    for f in wall
                        .balconies
                        .iter()
                        .filter_map(|bc| balcony_faces(wall, bc))
                    {
                        for p in f.all().flat_map(|f| f.outer.iter()) {
                            lo = lo.min(*p);
                            hi = hi.max(*p);
                        }
                    }
                    // And so do the window sills.
                    for f in wall_sill_faces(wall) {
                        for p in &f.outer {
                            lo = lo.min(*p);
                            hi = hi.max(*p);
                        }
                    }
                }
                // And the cornice and eaves (issue 49).
                let trim = cornice_solids(part).into_iter().chain(eaves_solids(part));
                for s in trim {
                    for p in s.faces.iter().flat_map(|f| f.outer.iter()) {
                        lo = lo.min(*p);
                        hi = hi.max(*p);
                    }
                }
            }
        }
        let x = &mut *self.x;
        x.s("<gml:boundedBy>\n<gml:Envelope srsName=\"");
        x.s(self.srs);
        x.s("\" srsDimension=\"3\">\n<gml:lowerCorner>");
        x.point(self.origin + lo);
        x.s("</gml:lowerCorner>\n<gml:upperCorner>");
        x.point(self.origin + hi);
        x.s("</gml:upperCorner>\n</gml:Envelope>\n</gml:boundedBy>\n");
    }

    fn string_attribute(&mut self, name: &str, value: &str) {
        let x = &mut *self.x;
        x.s("<gen:stringAttribute name=\"");
        x.escaped(name, true);
        x.s("\">\n<gen:value>");
        x.escaped(value, false);
        x.s("</gen:value>\n</gen:stringAttribute>\n");
    }

    /// The building's provenance ([`crate::model::Provenance`]): `storeysSource`,
    /// `heightSource` and `roofSource` as strings, `storeysError`, `heightError` (metres) and
    /// `roofProbability` as doubles, each left out when unknown.
    fn provenance(&mut self, p: &Provenance) {
        let values = [
            ("storeys", p.storeys, "Error", p.storeys_error),
            ("height", p.height, "Error", p.height_error),
            ("roof", p.roof, "Probability", p.roof_probability),
        ];
        for (what, source, suffix, value) in values {
            self.string_attribute(&format!("{what}Source"), source.name());
            if let Some(v) = value {
                let x = &mut *self.x;
                x.s("<gen:doubleAttribute name=\"");
                x.s(what);
                x.s(suffix);
                x.s("\">\n<gen:value>");
                x.fixed3(v);
                x.s("</gen:value>\n</gen:doubleAttribute>\n");
            }
        }
    }

    /// The input file's other attributes (issue 47), typed: `gen:stringAttribute`,
    /// `gen:intAttribute`, `gen:doubleAttribute`, `gen:dateAttribute` (an `xs:date`; a
    /// date-time stays a string), a boolean as the string `true`/`false`.
    fn input_attributes(&mut self, a: &Attributes) {
        for (name, value) in a.iter() {
            let (element, text) = match value {
                AttrValue::Text(t) => ("stringAttribute", t.to_string()),
                AttrValue::Int(i) => ("intAttribute", i.to_string()),
                AttrValue::Real(r) => ("doubleAttribute", r.to_string()),
                AttrValue::Bool(b) => ("stringAttribute", b.to_string()),
                AttrValue::Date(d) if is_xs_date(d) => ("dateAttribute", d.to_string()),
                AttrValue::Date(d) => ("stringAttribute", d.to_string()),
            };
            let x = &mut *self.x;
            x.s("<gen:");
            x.s(element);
            x.s(" name=\"");
            x.escaped(name, true);
            x.s("\">\n<gen:value>");
            x.escaped(&text, false);
            x.s("</gen:value>\n</gen:");
            x.s(element);
            x.s(">\n");
        }
    }

    fn building_attributes(&mut self, roof: RoofShape, height: f64, storeys: u32) {
        let x = &mut *self.x;
        x.s("<bldg:roofType codeSpace=\"");
        x.s(ROOF_TYPE_CODESPACE);
        x.s("\">");
        x.s(roof.citygml_code());
        x.s("</bldg:roofType>\n<bldg:measuredHeight uom=\"m\">");
        x.fixed3(height);
        x.s("</bldg:measuredHeight>\n<bldg:storeysAboveGround>");
        x.uint(u64::from(storeys));
        x.s("</bldg:storeysAboveGround>\n");
    }
}

/// Whether `d` is an `xs:date` as written by GIS files (`YYYY-MM-DD`).
pub(crate) fn is_xs_date(d: &str) -> bool {
    let b = d.as_bytes();
    b.len() == 10
        && b[4] == b'-'
        && b[7] == b'-'
        && b.iter()
            .enumerate()
            .all(|(i, c)| i == 4 || i == 7 || c.is_ascii_digit())
}
