//! Styles, materials and property sets of the IFC writer: surface styles and renderings per
//! colour and surface material (`crate::color::material`), material layer set usages per wall thickness, their associations, and the building's
//! property sets.

use std::collections::BTreeMap;

use crate::color::material::Material;
use crate::color::Color;
use crate::export::step::{Id, StepBuf};
use crate::export::ExportError;
use crate::model::Building;

use super::Render;

impl Render<'_> {
    /// One `IfcRelAssociatesMaterial` per material layer set usage, for the walls using it.
    pub(super) fn associate_materials(
        &mut self,
        key: &str,
        pk: &str,
        by_usage: BTreeMap<Id, Vec<Id>>,
    ) -> Result<(), ExportError> {
        for (usage, ids) in by_usage {
            // The path holds the usage's entity number: that of one made by this building is
            // known only when the rendering is exact.
            let number = match self.start {
                _ if !usage.is_local() => usage.0,
                Some(start) => usage.relocate(start).0,
                None => {
                    self.inexact = true;
                    0
                }
            };
            self.w.entity("IFCRELASSOCIATESMATERIAL", |a| {
                a.guid(key, &format!("{pk}/material/{number}"))
                    .opt_id(self.g.owner)
                    .null()
                    .null();
                a.ids(&ids).id(usage);
            })?;
        }
        Ok(())
    }

    /// The shared surface style of a colour and a surface material: a shading of the colour
    /// when no material is known, else a rendering with the material's reflectance
    /// ([`Render::rendering`]).
    fn style(&mut self, c: Color, m: Material) -> Result<Id, ExportError> {
        if m != Material::Unspecified {
            let transparency = 1.0 - f64::from(if c.a.is_finite() { c.a } else { 1.0 });
            return self.rendering(c, transparency, m);
        }
        let key = color_key(c);
        if let Some(id) = self.styles.get(&(key, m)) {
            return Ok(id);
        }
        let rgb = self.w.entity("IFCCOLOURRGB", |a| {
            a.null()
                .real(f64::from(key[0]) / 1000.0)
                .real(f64::from(key[1]) / 1000.0)
                .real(f64::from(key[2]) / 1000.0);
        })?;
        let schema = self.g.schema;
        let shading = self.w.entity("IFCSURFACESTYLESHADING", |a| {
            a.id(rgb);
            if !schema.ifc4_attributes() {
                // (IFC2X3 has no Transparency here.)
            } else if key[3] < 1000 {
                a.real(1.0 - f64::from(key[3]) / 1000.0);
            } else {
                a.null();
            }
        })?;
        let name = c.to_hex();
        let style = self.w.entity("IFCSURFACESTYLE", |a| {
            a.string(&name).enumeration("BOTH").ids(&[shading]);
        })?;
        let style = self.style_assignment(style)?;
        self.styles.insert((key, m), style);
        Ok(style)
    }

    /// What an `IfcStyledItem` refers to for surface style `style`: the style, or in IFC2X3
    /// an `IfcPresentationStyleAssignment` of it (cached with the style).
    fn style_assignment(&mut self, style: Id) -> Result<Id, ExportError> {
        if !self.g.schema.style_assignments() {
            return Ok(style);
        }
        Ok(self.w.entity("IFCPRESENTATIONSTYLEASSIGNMENT", |a| {
            a.ids(&[style]);
        })?)
    }

    /// Styles `item` in colour `c` of no known material.
    pub(super) fn styled(&mut self, item: Id, c: Color) -> Result<(), ExportError> {
        self.styled_as(item, c, Material::Unspecified)
    }

    /// Styles `item` in colour `c` and surface material `m` ([`Render::style`]).
    pub(super) fn styled_as(&mut self, item: Id, c: Color, m: Material) -> Result<(), ExportError> {
        let style = self.style(c, m)?;
        self.w.entity("IFCSTYLEDITEM", |a| {
            a.id(item).ids(&[style]).null();
        })?;
        Ok(())
    }

    /// The shared material layer set usage of a wall thickness.
    pub(super) fn usage(&mut self, thickness: f64) -> Result<Id, ExportError> {
        let key = (thickness * 1e6).round() as i64;
        if let Some(id) = self.usages.get(&key) {
            return Ok(id);
        }
        let t = key as f64 / 1e6;
        let mat = self.g.wall_material;
        let ifc4 = self.g.schema.ifc4_attributes();
        let layer = self.w.entity("IFCMATERIALLAYER", |a| {
            a.id(mat).real(t).null();
            if ifc4 {
                a.string("Wall").null().null().null();
            }
        })?;
        let name = format!("Wall {:.0} mm", t * 1000.0);
        let set = self.w.entity("IFCMATERIALLAYERSET", |a| {
            a.ids(&[layer]).string(&name);
            if ifc4 {
                a.null();
            }
        })?;
        let usage = self.w.entity("IFCMATERIALLAYERSETUSAGE", |a| {
            a.id(set)
                .enumeration("AXIS2")
                .enumeration("POSITIVE")
                .real(0.0);
            if ifc4 {
                a.null();
            }
        })?;
        self.usages.insert(key, usage);
        Ok(usage)
    }

    /// The shared rendering style of a colour with a transparency (0 opaque .. 1 invisible)
    /// and a surface material: with a known material, its `SpecularHighlight`
    /// (`IfcSpecularRoughness`, [`Material::specular_roughness`]) and `ReflectanceMethod`
    /// ([`Material::reflectance_method`]) and its name after the colour's; else neither
    /// (`NOTDEFINED`).
    fn rendering(&mut self, c: Color, transparency: f64, m: Material) -> Result<Id, ExportError> {
        let ck = color_key(c);
        let tk = (transparency.clamp(0.0, 1.0) * 1000.0).round() as u16;
        if let Some(id) = self.shared.renderings.get(&(ck, tk, m)) {
            return Ok(id);
        }
        let rgb = self.w.entity("IFCCOLOURRGB", |a| {
            a.null()
                .real(f64::from(ck[0]) / 1000.0)
                .real(f64::from(ck[1]) / 1000.0)
                .real(f64::from(ck[2]) / 1000.0);
        })?;
        let rendering = self.w.entity("IFCSURFACESTYLERENDERING", |a| {
            a.id(rgb);
            if tk > 0 {
                a.real(f64::from(tk) / 1000.0);
            } else {
                a.null();
            }
            a.null().null().null().null().null();
            if m == Material::Unspecified {
                a.null();
            } else {
                a.typed("IFCSPECULARROUGHNESS", |t| {
                    t.real(f64::from(m.specular_roughness()));
                });
            }
            let method = m.reflectance_method().ifc();
            a.enumeration(method.trim_matches('.'));
        })?;
        let mut name = if tk > 0 {
            format!("{} {}%", c.to_hex(), tk / 10)
        } else {
            c.to_hex()
        };
        if m != Material::Unspecified {
            name.push(' ');
            name.push_str(m.name());
        }
        let style = self.w.entity("IFCSURFACESTYLE", |a| {
            a.string(&name).enumeration("BOTH").ids(&[rendering]);
        })?;
        let style = self.style_assignment(style)?;
        self.shared.renderings.insert((ck, tk, m), style);
        Ok(style)
    }

    /// Styles `item` with the rendering of `c`, `transparency` and `m` ([`Render::rendering`]).
    pub(super) fn rendered(
        &mut self,
        item: Id,
        c: Color,
        transparency: f64,
        m: Material,
    ) -> Result<(), ExportError> {
        let style = self.rendering(c, transparency, m)?;
        self.w.entity("IFCSTYLEDITEM", |a| {
            a.id(item).ids(&[style]).null();
        })?;
        Ok(())
    }

    pub(super) fn building_psets(
        &mut self,
        b: &Building,
        key: &str,
        building: Id,
    ) -> Result<(), ExportError> {
        let mut props = Vec::new();
        let source = b.id.to_string();
        let single = |w: &mut StepBuf,
                      name: &str,
                      ty: &str,
                      f: &dyn Fn(&mut crate::export::step::Args<'_>)| {
            w.entity("IFCPROPERTYSINGLEVALUE", |a| {
                a.string(name).null().typed(ty, |t| f(t)).null();
            })
        };
        props.push(single(&mut self.w, "SourceId", "IFCIDENTIFIER", &|t| {
            t.string(&source);
        })?);
        props.push(single(&mut self.w, "Zone", "IFCLABEL", &|t| {
            t.string(&b.zone);
        })?);
        props.push(single(&mut self.w, "Appearance", "IFCLABEL", &|t| {
            t.string(&b.appearance);
        })?);
        props.push(single(
            &mut self.w,
            "MeasuredHeight",
            "IFCLENGTHMEASURE",
            &|t| {
                t.real(b.measured_height);
            },
        )?);
        props.push(single(&mut self.w, "Lod", "IFCINTEGER", &|t| {
            t.int(i64::from(b.lod.number()));
        })?);
        props.push(single(&mut self.w, "RoofShape", "IFCLABEL", &|t| {
            t.string(b.roof_shape.osm_name());
        })?);
        // Where storeys, height and roof came from; an unknown uncertainty is left out. A
        // height error may be 0 (a fixed KB height): IfcLengthMeasure, not the positive one.
        let p = &b.provenance;
        let values = [
            ("Storeys", p.storeys, "Error", p.storeys_error, "IFCREAL"),
            (
                "Height",
                p.height,
                "Error",
                p.height_error,
                "IFCLENGTHMEASURE",
            ),
            (
                "Roof",
                p.roof,
                "Probability",
                p.roof_probability,
                "IFCNORMALISEDRATIOMEASURE",
            ),
        ];
        for (what, source, suffix, value, ty) in values {
            props.push(single(
                &mut self.w,
                &format!("{what}Source"),
                "IFCLABEL",
                &|t| {
                    t.string(source.name());
                },
            )?);
            if let Some(v) = value {
                props.push(single(&mut self.w, &format!("{what}{suffix}"), ty, &|t| {
                    t.real(v);
                })?);
            }
        }
        // A building of one part that is a building:part (its outline not drawn): the part's id.
        if let [part] = b.parts.as_slice() {
            if let Some(source) = part.traced_source(b.id) {
                let source = source.to_string();
                props.push(single(
                    &mut self.w,
                    "PartSourceId",
                    "IFCIDENTIFIER",
                    &|t| {
                        t.string(&source);
                    },
                )?);
            }
            // What the building is when it is no house (issue 45).
            if let Some(class) = part.structure {
                props.push(single(&mut self.w, "Structure", "IFCLABEL", &|t| {
                    t.string(class.name());
                })?);
            }
        }
        let storeys = single(&mut self.w, "NumberOfStoreys", "IFCINTEGER", &|t| {
            t.int(i64::from(b.storeys_above_ground));
        })?;
        self.pset(key, "pset/source", "Citygen_Source", &props, &[building])?;
        // The input file's other attributes (issue 47), typed; a date as its ISO 8601 text.
        if let Some(a) = &b.attributes {
            use crate::model::AttrValue;
            let mut props = Vec::with_capacity(a.len());
            for (name, value) in a.iter() {
                let ty = match value {
                    AttrValue::Text(_) | AttrValue::Date(_) => "IFCLABEL",
                    AttrValue::Int(_) => "IFCINTEGER",
                    AttrValue::Real(_) => "IFCREAL",
                    AttrValue::Bool(_) => "IFCBOOLEAN",
                };
                props.push(self.w.entity("IFCPROPERTYSINGLEVALUE", |a| {
                    a.string(name)
                        .null()
                        .typed(ty, |t| {
                            match value {
                                AttrValue::Text(v) | AttrValue::Date(v) => t.string(v),
                                AttrValue::Int(i) => t.int(*i),
                                AttrValue::Real(r) => t.real(*r),
                                AttrValue::Bool(b) => t.boolean(*b),
                            };
                        })
                        .null();
                })?);
            }
            self.pset(
                key,
                "pset/attributes",
                "Citygen_Attributes",
                &props,
                &[building],
            )?;
        }
        self.pset(
            key,
            "pset/common",
            "Pset_BuildingCommon",
            &[storeys],
            &[building],
        )
    }

    /// An `IfcPropertySet` `name` of `props` (GlobalId path `path`) and the
    /// `IfcRelDefinesByProperties` (`{path}/rel`) that puts it on `objects`.
    fn pset(
        &mut self,
        key: &str,
        path: &str,
        name: &str,
        props: &[Id],
        objects: &[Id],
    ) -> Result<(), ExportError> {
        let pset = self.w.entity("IFCPROPERTYSET", |a| {
            a.guid(key, path)
                .opt_id(self.g.owner)
                .string(name)
                .null()
                .ids(props);
        })?;
        self.w.entity("IFCRELDEFINESBYPROPERTIES", |a| {
            a.guid(key, &format!("{path}/rel"))
                .opt_id(self.g.owner)
                .null()
                .null()
                .ids(objects)
                .id(pset);
        })?;
        Ok(())
    }

    /// The `Citygen_Part` property set on the partial building of a part (issue 45): its
    /// `Height` and `MinHeight` above the building's ground (`IfcLengthMeasure`, as OSM's
    /// `height` and `min_height`), `NumberOfStoreys` (`IfcInteger`), `RoofShape` (`IfcLabel`,
    /// OSM `roof:shape`), and where the part is traced ([`crate::model::Part::traced_source`])
    /// its `SourceId` (`IfcIdentifier`) and, on an outline's rest, `SourceRole`
    /// (`outline-rest`); on a structure, its `Structure` (`IfcLabel`,
    /// [`crate::model::Structure::name`]).
    pub(super) fn part_pset(
        &mut self,
        part: &crate::model::Part,
        b: &Building,
        key: &str,
        partial: Id,
    ) -> Result<(), ExportError> {
        let mut props = Vec::with_capacity(6);
        let mut single = |w: &mut StepBuf,
                          name: &str,
                          ty: &str,
                          f: &dyn Fn(&mut crate::export::step::Args<'_>)| {
            w.entity("IFCPROPERTYSINGLEVALUE", |a| {
                a.string(name).null().typed(ty, |t| f(t)).null();
            })
            .map(|id| props.push(id))
        };
        if let Some(source) = part.traced_source(b.id) {
            let source = source.to_string();
            single(&mut self.w, "SourceId", "IFCIDENTIFIER", &|t| {
                t.string(&source);
            })?;
        }
        if let Some(role) = part.role.name() {
            single(&mut self.w, "SourceRole", "IFCLABEL", &|t| {
                t.string(role);
            })?;
        }
        if let Some(class) = part.structure {
            single(&mut self.w, "Structure", "IFCLABEL", &|t| {
                t.string(class.name());
            })?;
        }
        single(&mut self.w, "Height", "IFCLENGTHMEASURE", &|t| {
            t.real(part.height_above(b.ground_z));
        })?;
        single(&mut self.w, "MinHeight", "IFCLENGTHMEASURE", &|t| {
            t.real(part.base_z - b.ground_z);
        })?;
        single(&mut self.w, "NumberOfStoreys", "IFCINTEGER", &|t| {
            t.int(i64::from(part.storeys));
        })?;
        single(&mut self.w, "RoofShape", "IFCLABEL", &|t| {
            t.string(part.roof_shape.osm_name());
        })?;
        let path = format!("{}/pset/source", part.key);
        self.pset(key, &path, "Citygen_Part", &props, &[partial])
    }

    /// The property sets of a building's walls, given with their party-wall shares
    /// ([`crate::model::Wall::party`]): `Pset_WallCommon` with IsExternal true on the walls
    /// that face the outside at least in part, false on those wholly against a neighbour (a
    /// party wall faces no outside); and a `Citygen_Wall` set with `PartyWallShare` (an
    /// `IfcNormalisedRatioMeasure`, to the hundredth) on every wall that faces a neighbour,
    /// one set per distinct share.
    pub(super) fn wall_psets(&mut self, key: &str, walls: &[(Id, f64)]) -> Result<(), ExportError> {
        let party = |s: f64| s >= 0.995;
        let outside: Vec<Id> = walls.iter().filter(|w| !party(w.1)).map(|w| w.0).collect();
        let against: Vec<Id> = walls.iter().filter(|w| party(w.1)).map(|w| w.0).collect();
        if !outside.is_empty() {
            self.wall_common(key, "walls/pset", true, &outside)?;
        }
        if !against.is_empty() {
            self.wall_common(key, "walls/party/pset", false, &against)?;
        }
        let mut by_share: std::collections::BTreeMap<u32, Vec<Id>> = Default::default();
        for &(id, s) in walls {
            let hundredths = (s.clamp(0.0, 1.0) * 100.0).round() as u32;
            if hundredths > 0 {
                by_share.entry(hundredths).or_default().push(id);
            }
        }
        for (h, ids) in by_share {
            let prop = self.w.entity("IFCPROPERTYSINGLEVALUE", |a| {
                a.string("PartyWallShare")
                    .null()
                    .typed("IFCNORMALISEDRATIOMEASURE", |t| {
                        t.real(f64::from(h) / 100.0);
                    });
                a.null();
            })?;
            self.pset(
                key,
                &format!("walls/party/{h}"),
                "Citygen_Wall",
                &[prop],
                &ids,
            )?;
        }
        Ok(())
    }

    /// A `Pset_WallCommon` with IsExternal `external` (GlobalId path `path`, its relation
    /// `{path}/rel`) on `walls`.
    pub(super) fn wall_common(
        &mut self,
        key: &str,
        path: &str,
        external: bool,
        walls: &[Id],
    ) -> Result<(), ExportError> {
        let prop = self.w.entity("IFCPROPERTYSINGLEVALUE", |a| {
            a.string("IsExternal").null().typed("IFCBOOLEAN", |t| {
                t.boolean(external);
            });
            a.null();
        })?;
        self.pset(key, path, "Pset_WallCommon", &[prop], walls)
    }
}

/// A colour as a cache key (components in thousandths).
pub(super) fn color_key(c: Color) -> [u16; 4] {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 1000.0).round() as u16;
    [q(c.r), q(c.g), q(c.b), q(c.a)]
}
