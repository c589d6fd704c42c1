//! Material binding: UsdShadeMaterialBindingAPI resolution, with binding strength and GeomSubsets.

use anyhow::Result;

use super::*;

impl Reader<'_> {
    /// The bound material: the prim's own binding, else the nearest ancestor's (purpose
    /// `full`, falling back to all-purpose).
    pub(super) fn bound_material(&mut self, prim: &Prim) -> Result<Option<String>> {
        let key = prim.path().as_str().to_string();
        if let Some(m) = self.bindings.get(&key) {
            return Ok(m.clone());
        }
        let m = self.resolve_binding(prim)?;
        self.bindings.insert(key, m.clone());
        Ok(m)
    }

    /// [`Self::bound_material`] without the cache: UsdShade's resolution (the crate's
    /// `compute_bound_material`), from the prim itself whether or not it applies
    /// MaterialBindingAPI, with collection bindings asked about the prim. A binding that wins
    /// but targets no Material binds nothing (warned), as in usd-core.
    pub(super) fn resolve_binding(&mut self, prim: &Prim) -> Result<Option<String>> {
        if self.malformed_binding_above(prim)? {
            return Ok(None);
        }
        let mut not_materials = Vec::new();
        let api = MaterialBindingAPI::at(self.stage, prim.path().clone());
        let mut cache = std::mem::take(&mut self.binding_cache);
        let m = api.compute_bound_material_with("full", &mut cache, &mut |target| {
            let material = self.is_material_target(target)?;
            if !material {
                not_materials.push(target.as_str().to_string());
            }
            Ok(material)
        });
        self.binding_cache = cache;
        let m = m?;
        for t in not_materials {
            self.out.warnings.push(format!(
                "{t}: material bindings target it, but it is not a Material prim; prims bound to it show their displayColor"
            ));
        }
        let Some(m) = m else { return Ok(None) };
        if !well_formed_path(m.as_str()) {
            self.out.warnings.push(format!("{}: bound material '{}' is not a valid path; the binding is ignored", prim.path(), m.as_str()));
            return Ok(None);
        }
        Ok(Some(m.as_str().to_string()))
    }

    /// A Material prim, or a prim inside a MaterialX document that a reference brings in
    /// (usdMtlx composes those as Materials; the crate cannot read the document).
    fn is_material_target(&self, target: &sdf::Path) -> Result<bool> {
        let typed = self.stage.prim(target.clone()).type_name()?;
        Ok(typed.is_some_and(|t| t.as_str() == "Material") || self.mtlx_reference(target.as_str())?.is_some())
    }

    /// True when a `material:binding` relationship on the prim or an ancestor targets
    /// something that is not a path at all (warned): the prim's binding is then ignored.
    fn malformed_binding_above(&mut self, prim: &Prim) -> Result<bool> {
        let mut cur = Some(prim.path().clone());
        while let Some(path) = cur {
            if path.as_str() == "/" || path.as_str().is_empty() {
                break;
            }
            let here = self.stage.prim(path.clone());
            let mut broken = false;
            for rel in here.relationships()? {
                let name = rel.path().name().unwrap_or_default().to_string();
                if !name.starts_with("material:binding") {
                    continue;
                }
                for t in rel.targets()?.iter().filter(|t| !well_formed_path(t.as_str())) {
                    self.out.warnings.push(format!(
                        "{path}: relationship '{name}' targets '{}', which is not a valid path; the binding is ignored",
                        t.as_str()
                    ));
                    broken = true;
                }
            }
            if broken {
                return Ok(true);
            }
            cur = path.parent();
        }
        Ok(false)
    }
}
