//! Cornices and eaves of the IFC writer (issue 49): each an `IfcBuildingElementProxy` of the
//! part's top storey (`Cornice`, `Eaves`; IFC4: `.USERDEFINED.` with that ObjectType), its body
//! one closed `IfcFacetedBrep` per run or board (`crate::export::lod3geom::cornice_solids`,
//! `eaves_solids`), styled in the cornice's colour or the roof's.

use glam::DVec3;

use crate::export::lod3geom::{cornice_solids, eaves_solids, trim_color};
use crate::export::step::{Args, Id};
use crate::export::ExportError;
use crate::model::Part;

use super::roofs::is_closed_shell;
use super::shapes::clean3;
use super::{ElementFrame, Render};

impl Render<'_> {
    /// `part`'s cornice (`eaves` false) or eaves as a proxy with global id `gid`, placed in
    /// `frame`; `None` when the part has none (or no solid closes once cleaned).
    pub(super) fn trim(
        &mut self,
        part: &Part,
        frame: &ElementFrame,
        gid: &str,
        eaves: bool,
    ) -> Result<Option<Id>, ExportError> {
        let solids = if eaves {
            eaves_solids(part)
        } else {
            cornice_solids(part)
        };
        // The top's colour and material (the eaves' roof, the cornice's own) for the body.
        let (color, material) = trim_color(part, eaves, 0);
        let mut items = Vec::with_capacity(solids.len());
        for s in &solids {
            let shell: Vec<Vec<Vec<DVec3>>> = s
                .faces
                .iter()
                .map(|f| {
                    vec![clean3(
                        &f.outer
                            .iter()
                            .map(|p| *p - frame.origin)
                            .collect::<Vec<_>>(),
                    )]
                })
                .collect();
            if shell.iter().any(|f| f[0].len() < 3) || !is_closed_shell(&shell) {
                continue;
            }
            let item = self.brep(&shell)?;
            self.styled_as(item, color, material)?;
            items.push(item);
        }
        if items.is_empty() {
            return Ok(None);
        }
        let body_ctx = self.g.body_ctx;
        let rep = self.representation(body_ctx, "Body", "Brep", &items)?;
        let shape = self.shape(&[rep])?;
        let pl = self.placement(frame.placement, DVec3::ZERO, DVec3::X)?;
        let (name, object_type) = if eaves {
            ("Eaves", "Eaves")
        } else {
            ("Cornice", "Cornice")
        };
        let id = self.proxy(|a| a.string(gid), name, object_type, pl, shape)?;
        Ok(Some(id))
    }

    /// An `IfcBuildingElementProxy` named `name` of ObjectType `object_type` (IFC4 and later:
    /// PredefinedType `.USERDEFINED.`), placed at `pl` with the shape `shape`; `global_id`
    /// writes its GlobalId.
    pub(super) fn proxy(
        &mut self,
        global_id: impl for<'a, 'b> FnOnce(&'a mut Args<'b>) -> &'a mut Args<'b>,
        name: &str,
        object_type: &str,
        pl: Id,
        shape: Id,
    ) -> Result<Id, ExportError> {
        let ifc4 = self.g.schema.ifc4_attributes();
        let owner = self.g.owner;
        Ok(self.w.entity("IFCBUILDINGELEMENTPROXY", |a| {
            global_id(a)
                .opt_id(owner)
                .string(name)
                .null()
                .string(object_type)
                .id(pl)
                .id(shape)
                .null();
            if ifc4 {
                a.enumeration("USERDEFINED");
            } else {
                a.null();
            }
        })?)
    }
}
