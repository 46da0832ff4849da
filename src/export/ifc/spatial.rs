//! Spatial structure of the IFC writer: the file's header entities (project, units, contexts,
//! map conversion, site) and final relations, buildings (partial buildings of composite ones),
//! storeys, and how a part's elements are laid out in its storeys (LOD1/LOD2 and LOD3).

use std::collections::{BTreeMap, BTreeSet};
use std::io::Write;

use glam::{DVec2, DVec3};

use crate::export::step::{global_id, Header, Id, StepWriter};
use crate::export::{vertical_datum, ExportError, OutputContext};
use crate::model::{Building, Lod, Part};

use super::openings::Host;
use super::schema::IfcSchema;
use super::{
    compound_angle, Caches, ElementFrame, Globals, Open, Render, EPS, MAX_STOREYS,
    SHARED_CACHE_LIMIT,
};

impl<W: Write> Open<W> {
    pub(super) fn begin(
        out: W,
        ctx: &OutputContext,
        file_name: &str,
        schema: IfcSchema,
    ) -> Result<Open<W>, ExportError> {
        let mut w = StepWriter::new(out);
        let mut header = Header::new(file_name, schema.name());
        header.description = vec![schema.view_definition().to_string()];
        w.write_header(&header)?;
        let ns = format!("{}#{}", ctx.source_name, ctx.seed);
        let owner = if schema.owner_history() {
            Some(owner_history(&mut w)?)
        } else {
            None
        };

        let origin3 = w.entity("IFCCARTESIANPOINT", |a| {
            a.reals(&[0.0, 0.0, 0.0]);
        })?;
        let origin2 = w.entity("IFCCARTESIANPOINT", |a| {
            a.reals(&[0.0, 0.0]);
        })?;
        let mut dir = |v: &[f64]| {
            w.entity("IFCDIRECTION", |a| {
                a.reals(v);
            })
        };
        let dir_x = dir(&[1.0, 0.0, 0.0])?;
        let dir_z = dir(&[0.0, 0.0, 1.0])?;
        let dir_neg_y = dir(&[0.0, -1.0, 0.0])?;
        let dir_neg_z = dir(&[0.0, 0.0, -1.0])?;
        let true_north = dir(&[0.0, 1.0])?;
        let identity = w.entity("IFCAXIS2PLACEMENT3D", |a| {
            a.id(origin3).null().null();
        })?;

        let model_ctx = w.entity("IFCGEOMETRICREPRESENTATIONCONTEXT", |a| {
            a.null()
                .string("Model")
                .int(3)
                .real(1e-5)
                .id(identity)
                .id(true_north);
        })?;
        let sub = |w: &mut StepWriter<W>, ident: &str, view: &str| {
            w.entity("IFCGEOMETRICREPRESENTATIONSUBCONTEXT", |a| {
                a.string(ident)
                    .string("Model")
                    .derived()
                    .derived()
                    .derived()
                    .derived();
                a.id(model_ctx).null().enumeration(view).null();
            })
        };
        let body_ctx = sub(&mut w, "Body", "MODEL_VIEW")?;
        let axis_ctx = sub(&mut w, "Axis", "GRAPH_VIEW")?;

        let mut si = |kind: &str, name: &str| {
            w.entity("IFCSIUNIT", |a| {
                a.derived().enumeration(kind).null().enumeration(name);
            })
        };
        let metre = si("LENGTHUNIT", "METRE")?;
        let units = [
            metre,
            si("AREAUNIT", "SQUARE_METRE")?,
            si("VOLUMEUNIT", "CUBIC_METRE")?,
            si("PLANEANGLEUNIT", "RADIAN")?,
        ];
        let unit_assignment = w.entity("IFCUNITASSIGNMENT", |a| {
            a.ids(&units);
        })?;
        let project = w.entity("IFCPROJECT", |a| {
            a.guid(&ns, "project")
                .opt_id(owner)
                .string(&ctx.source_name);
            a.string(&format!(
                "citygen model of {} (LOD{}, seed {})",
                ctx.source_name,
                ctx.lod.number(),
                ctx.seed
            ));
            a.null().null().null().ids(&[model_ctx]).id(unit_assignment);
        })?;

        if schema.ifc4_attributes() {
            map_conversion(&mut w, ctx, model_ctx, metre)?;
        }

        let site_placement = w.entity("IFCLOCALPLACEMENT", |a| {
            a.null().id(identity);
        })?;
        let (lon, lat) = ctx.origin_lonlat;
        let site = w.entity("IFCSITE", |a| {
            a.guid(&ns, "site")
                .opt_id(owner)
                .string("Site")
                .null()
                .null()
                .id(site_placement);
            a.null().null().enumeration("ELEMENT");
            match compound_angle(lat).filter(|_| lat.abs() <= 90.0) {
                Some(v) => a.ints(&v),
                None => a.null(),
            };
            match compound_angle(lon) {
                Some(v) => a.ints(&v),
                None => a.null(),
            };
            a.real(ctx.origin.z).null().null();
        })?;
        w.entity("IFCRELAGGREGATES", |a| {
            a.guid(&ns, "project/site")
                .opt_id(owner)
                .null()
                .null()
                .id(project)
                .ids(&[site]);
        })?;
        let wall_material = w.entity("IFCMATERIAL", |a| {
            a.string("Wall");
            if schema.ifc4_attributes() {
                a.null().string("Wall");
            }
        })?;

        Ok(Open {
            w,
            g: Globals {
                ns,
                origin3,
                origin2,
                dir_x,
                dir_z,
                dir_neg_y,
                dir_neg_z,
                identity,
                body_ctx,
                axis_ctx,
                site_placement,
                wall_material,
                origin_z: ctx.origin.z,
                lod3: ctx.lod >= Lod::Lod3,
                schema,
                owner,
                position: schema.position_mandatory().then_some(identity),
            },
            site,
            project,
            caches: Caches::new(SHARED_CACHE_LIMIT),
            occurrences: BTreeMap::new(),
            buildings: Vec::new(),
            pool: Vec::new(),
            keys: BTreeSet::new(),
            terrain: ctx.terrain.clone(),
            max_bytes: None,
            occurrence_count: 0,
        })
    }

    pub(super) fn finish(mut self) -> Result<W, ExportError> {
        if let Some(t) = self.terrain.take() {
            self.terrain(&t)?;
        }
        if !self.buildings.is_empty() {
            let (gid, site, buildings) = (
                global_id(&self.g.ns, "site/buildings"),
                self.site,
                &self.buildings,
            );
            let owner = self.g.owner;
            self.w.entity("IFCRELAGGREGATES", |a| {
                a.string(&gid)
                    .opt_id(owner)
                    .null()
                    .null()
                    .id(site)
                    .ids(buildings);
            })?;
        }
        // Window and door types: one IfcRelDefinesByType each (a type has at most one), and
        // all declared in the project.
        let mut declared = Vec::with_capacity(self.caches.types.map.len());
        for (key, &(id, _)) in &self.caches.types.map {
            let Some(occurrences) = self.occurrences.get(key).filter(|o| !o.is_empty()) else {
                continue;
            };
            let gid = global_id(&self.g.ns, &format!("type/{}/rel", key.name()));
            let owner = self.g.owner;
            self.w.entity("IFCRELDEFINESBYTYPE", |a| {
                a.string(&gid)
                    .opt_id(owner)
                    .null()
                    .null()
                    .ids(occurrences)
                    .id(id);
            })?;
            declared.push(id);
        }
        // (IFC2X3 has no IfcRelDeclares.)
        if !declared.is_empty() && self.g.schema.ifc4_attributes() {
            let (gid, project) = (global_id(&self.g.ns, "project/types"), self.project);
            self.w.entity("IFCRELDECLARES", |a| {
                a.string(&gid)
                    .null()
                    .null()
                    .null()
                    .id(project)
                    .ids(&declared);
            })?;
        }
        Ok(self.w.finish()?)
    }
}

impl Render<'_> {
    /// Storey `i` of part `pk` at elevation `elev` (relative to the building), placed relative to
    /// `holder_pl`: returns the storey and its placement.
    pub(super) fn storey(
        &mut self,
        key: &str,
        pk: &str,
        i: usize,
        holder_pl: Id,
        elev: f64,
    ) -> Result<(Id, Id), ExportError> {
        let pl = self.placement(holder_pl, DVec3::new(0.0, 0.0, elev), DVec3::X)?;
        let owner = self.g.owner;
        let storey = self.w.entity("IFCBUILDINGSTOREY", |a| {
            a.guid(key, &format!("{pk}/storey/{i}"))
                .opt_id(owner)
                .string(&format!("Storey {i}"));
            a.null()
                .null()
                .id(pl)
                .null()
                .null()
                .enumeration("ELEMENT")
                .real(elev);
        })?;
        Ok((storey, pl))
    }

    /// Writes building `b` (already checked finite) whose GlobalIds derive from `key`
    /// ([`Open::claim_key`]); returns its top-level `IfcBuilding`.
    pub(super) fn building(&mut self, b: &Building, key: &str) -> Result<Id, ExportError> {
        let anchor = b
            .parts
            .first()
            .and_then(|p| p.footprint.outer.first())
            .copied()
            .unwrap_or(DVec2::ZERO);
        let anchor = DVec3::new(anchor.x, anchor.y, b.base_z);
        let site_pl = self.g.site_placement;
        let placement = self.placement(site_pl, anchor, DVec3::X)?;
        let name = b.name.clone().unwrap_or_else(|| b.key());
        let description = format!("{} ({})", b.id, b.zone);
        let composite = b.parts.len() > 1;
        // Height of the building's +-0.00 above the CRS datum (storey elevations count from it).
        let datum_z = self.g.origin_z + b.base_z;
        let owner = self.g.owner;
        let building = self.w.entity("IFCBUILDING", |a| {
            a.guid(key, "building")
                .opt_id(owner)
                .string(&name)
                .string(&description)
                .null();
            a.id(placement).null().opt_string(b.name.as_deref());
            a.enumeration(if composite { "COMPLEX" } else { "ELEMENT" });
            a.real(datum_z).real(datum_z).null();
        })?;
        self.building_psets(b, key, building)?;
        self.building_quantities(b, key, building)?;

        let mut walls = Vec::new();
        if composite {
            let mut partials = Vec::with_capacity(b.parts.len());
            for part in &b.parts {
                let pl = self.placement(placement, DVec3::ZERO, DVec3::X)?;
                let pname = format!("{name} {}", part.key);
                let partial = self.w.entity("IFCBUILDING", |a| {
                    a.guid(key, &format!("{}/building", part.key))
                        .opt_id(owner)
                        .string(&pname);
                    a.null()
                        .null()
                        .id(pl)
                        .null()
                        .null()
                        .enumeration("PARTIAL")
                        .null()
                        .null()
                        .null();
                })?;
                partials.push(partial);
                self.part_pset(part, b, key, partial)?;
                self.part_quantities(part, key, partial)?;
                walls.extend(self.part(part, key, partial, pl, anchor)?);
            }
            self.w.entity("IFCRELAGGREGATES", |a| {
                a.guid(key, "building/parts")
                    .opt_id(owner)
                    .null()
                    .null()
                    .id(building)
                    .ids(&partials);
            })?;
        } else if let Some(part) = b.parts.first() {
            walls.extend(self.part(part, key, building, placement, anchor)?);
        }

        self.wall_psets(key, &walls)?;
        Ok(building)
    }

    /// Writes a part's storeys and elements under `holder` (the building or partial building,
    /// placed at `anchor`). Returns the ids of its walls with their party-wall shares.
    fn part(
        &mut self,
        part: &Part,
        key: &str,
        holder: Id,
        holder_pl: Id,
        anchor: DVec3,
    ) -> Result<Vec<(Id, f64)>, ExportError> {
        if self.g.lod3 {
            return self.part_lod3(part, key, holder, holder_pl, anchor);
        }
        let pk = &part.key;
        let n = part.storeys.clamp(1, MAX_STOREYS);
        let span = part.eave_z - part.base_z;
        let n = if span > EPS { n } else { 1 };
        let mut storeys = Vec::with_capacity(n as usize);
        let mut storey0_pl = holder_pl;
        for i in 0..n {
            let elev = part.base_z + span * f64::from(i) / f64::from(n) - anchor.z;
            let (storey, pl) = self.storey(key, pk, i as usize, holder_pl, elev)?;
            if i == 0 {
                storey0_pl = pl;
            }
            self.storey_quantities(key, part, i as usize, storey, span.max(0.0) / f64::from(n))?;
            storeys.push(storey);
        }
        let owner = self.g.owner;
        self.w.entity("IFCRELAGGREGATES", |a| {
            a.guid(key, &format!("{pk}/storeys"))
                .opt_id(owner)
                .null()
                .null()
                .id(holder)
                .ids(&storeys);
        })?;

        let frame = ElementFrame {
            origin: DVec3::new(anchor.x, anchor.y, part.base_z),
            placement: storey0_pl,
        };
        let mut contained = Vec::new();
        let mut by_usage: BTreeMap<Id, Vec<Id>> = BTreeMap::new();
        let mut walls = Vec::new();
        for (i, wall) in part.walls.iter().enumerate() {
            if let Some(id) = self.wall(
                part,
                wall,
                &frame,
                &global_id(key, &format!("{pk}/wall/{i}")),
                i,
            )? {
                let id = id.0;
                let usage = self.usage(wall.thickness)?;
                by_usage.entry(usage).or_default().push(id);
                walls.push((id, wall.party));
                contained.push(id);
            }
        }
        if let Some(id) = self.slab(part, &frame, &global_id(key, &format!("{pk}/slab")))? {
            contained.push(id);
        }
        if let Some(id) = self.roof(part, &frame, &global_id(key, &format!("{pk}/roof")))? {
            contained.push(id);
        }
        if !contained.is_empty() {
            let storey0 = storeys[0];
            self.w.entity("IFCRELCONTAINEDINSPATIALSTRUCTURE", |a| {
                a.guid(key, &format!("{pk}/contained"))
                    .opt_id(owner)
                    .null()
                    .null();
                a.ids(&contained).id(storey0);
            })?;
        }
        self.associate_materials(key, pk, by_usage)?;
        Ok(walls)
    }

    /// LOD3 part: one storey per entry of `part.levels` (elevation relative to the building),
    /// each wall in its storey (`Wall::storey`) with its openings, windows, doors and balconies;
    /// the base slab in the first storey and the roof in the top one. Returns the wall ids.
    fn part_lod3(
        &mut self,
        part: &Part,
        key: &str,
        holder: Id,
        holder_pl: Id,
        anchor: DVec3,
    ) -> Result<Vec<(Id, f64)>, ExportError> {
        let pk = &part.key;
        let mut levels: Vec<f64> = part
            .levels
            .iter()
            .copied()
            .take(MAX_STOREYS as usize)
            .collect();
        if levels.is_empty() {
            levels.push(part.base_z);
        }
        let mut storeys = Vec::with_capacity(levels.len());
        let mut frames = Vec::with_capacity(levels.len());
        for (i, &level) in levels.iter().enumerate() {
            let elev = level - anchor.z;
            let (storey, pl) = self.storey(key, pk, i, holder_pl, elev)?;
            let next = levels.get(i + 1).copied().unwrap_or(part.eave_z);
            self.storey_quantities(key, part, i, storey, (next - level).max(0.0))?;
            storeys.push(storey);
            frames.push(ElementFrame {
                origin: DVec3::new(anchor.x, anchor.y, level),
                placement: pl,
            });
        }
        let owner = self.g.owner;
        self.w.entity("IFCRELAGGREGATES", |a| {
            a.guid(key, &format!("{pk}/storeys"))
                .opt_id(owner)
                .null()
                .null()
                .id(holder)
                .ids(&storeys);
        })?;

        let top = storeys.len() - 1;
        let mut contained: Vec<Vec<Id>> = vec![Vec::new(); storeys.len()];
        let mut by_usage: BTreeMap<Id, Vec<Id>> = BTreeMap::new();
        let mut walls = Vec::new();
        for (i, wall) in part.walls.iter().enumerate() {
            let s = wall.storey.min(top);
            let path = format!("{pk}/wall/{i}");
            let Some((id, wall_pl)) =
                self.wall(part, wall, &frames[s], &global_id(key, &path), i)?
            else {
                continue;
            };
            let usage = self.usage(wall.thickness)?;
            by_usage.entry(usage).or_default().push(id);
            walls.push((id, wall.party));
            contained[s].push(id);
            for (j, o) in wall.openings.iter().enumerate() {
                let path = format!("{path}/opening/{j}");
                if let Some(fill) = self.opening(
                    &Host {
                        wall,
                        id,
                        placement: wall_pl,
                    },
                    o,
                    key,
                    &path,
                    (i, j),
                )? {
                    contained[s].push(fill);
                }
            }
            for (j, b) in wall.balconies.iter().enumerate() {
                let path = format!("{path}/balcony/{j}");
                let ids = self.balcony(wall, b, &frames[s], key, &path)?;
                contained[s].extend(ids);
            }
            if let Some(id) = self.sills(wall, &frames[s], key, &format!("{path}/sills"))? {
                contained[s].push(id);
            }
        }
        if !part.interior.is_empty() {
            self.interiors(part, key, &storeys, &frames, &mut contained, &mut by_usage)?;
        }
        if let Some(id) = self.slab(part, &frames[0], &global_id(key, &format!("{pk}/slab")))? {
            contained[0].push(id);
        }
        if let Some(id) = self.roof(part, &frames[top], &global_id(key, &format!("{pk}/roof")))? {
            contained[top].push(id);
        }
        // Cornice and eaves (issue 49), with the top storey.
        let asks = [part.cornice.is_some(), part.eaves.is_some()];
        for (eaves, what) in [(false, "cornice"), (true, "eaves")] {
            if !asks[usize::from(eaves)] {
                continue;
            }
            let gid = global_id(key, &format!("{pk}/{what}"));
            if let Some(id) = self.trim(part, &frames[top], &gid, eaves)? {
                contained[top].push(id);
            }
        }
        for (s, ids) in contained.iter().enumerate() {
            if ids.is_empty() {
                continue;
            }
            let path = if s == 0 {
                format!("{pk}/contained")
            } else {
                format!("{pk}/contained/{s}")
            };
            let storey = storeys[s];
            self.w.entity("IFCRELCONTAINEDINSPATIALSTRUCTURE", |a| {
                a.guid(key, &path).opt_id(owner).null().null();
                a.ids(ids).id(storey);
            })?;
        }
        self.associate_materials(key, pk, by_usage)?;
        Ok(walls)
    }
}

/// IFC2X3's mandatory owner history of rooted entities: citygen as person, organisation and
/// application, created at `SOURCE_DATE_EPOCH` (0 without it: never the clock).
fn owner_history<W: Write>(w: &mut StepWriter<W>) -> Result<Id, ExportError> {
    let person = w.entity("IFCPERSON", |a| {
        a.null().string("citygen");
        for _ in 0..6 {
            a.null();
        }
    })?;
    let org = w.entity("IFCORGANIZATION", |a| {
        a.null().string("citygen").null().null().null();
    })?;
    let user = w.entity("IFCPERSONANDORGANIZATION", |a| {
        a.id(person).id(org).null();
    })?;
    let app = w.entity("IFCAPPLICATION", |a| {
        a.id(org)
            .string(env!("CARGO_PKG_VERSION"))
            .string("citygen")
            .string("citygen");
    })?;
    let created = std::env::var("SOURCE_DATE_EPOCH")
        .ok()
        .and_then(|s| s.trim().parse::<i64>().ok())
        .filter(|&v| v >= 0)
        .unwrap_or(0);
    Ok(w.entity("IFCOWNERHISTORY", |a| {
        a.id(user).id(app).null().enumeration("ADDED");
        a.null().null().null().int(created);
    })?)
}

/// IFC4's georeferencing: an `IfcMapConversion` of the model context `model_ctx` to an
/// `IfcProjectedCRS` `EPSG:n` in `metre`s (with its vertical datum when the run states one).
fn map_conversion<W: Write>(
    w: &mut StepWriter<W>,
    ctx: &OutputContext,
    model_ctx: Id,
    metre: Id,
) -> Result<(), ExportError> {
    let epsg = ctx.crs.epsg();
    let mut crs_name = ctx.crs.name();
    // The heights' datum (issue 44): IfcProjectedCRS.VerticalDatum, an IfcIdentifier, holds
    // its EPSG code or, without one, its name; the description names the compound.
    let vertical = vertical_datum(ctx).map(|(code, name)| {
        crs_name = format!("{crs_name} + {name}");
        // (IfcIdentifier is at most 255 characters.)
        code.map_or_else(|| name.chars().take(255).collect(), |v| format!("EPSG:{v}"))
    });
    let crs = w.entity("IFCPROJECTEDCRS", |a| {
        a.string(&format!("EPSG:{epsg}")).string(&crs_name).null();
        match &vertical {
            Some(v) => a.string(v),
            None => a.null(),
        };
        a.null().null().id(metre);
    })?;
    w.entity("IFCMAPCONVERSION", |a| {
        a.id(model_ctx)
            .id(crs)
            .real(ctx.origin.x)
            .real(ctx.origin.y)
            .real(ctx.origin.z);
        a.real(1.0).real(0.0).real(1.0);
    })?;
    Ok(())
}
