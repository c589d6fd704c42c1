//! A syntax check of text USD layers before the openusd crate composes them. The crate's
//! parser accepts some malformed names and paths (a prim named `Prin}ipled`, a binding target
//! `</World/Looks/Grey()`) and its composition then recurses without end or loops: a stack
//! overflow or a hang, which no error handling can catch (found by fuzzing). This pass finds
//! such names and paths first and reports them by line, as a parse error would; the reader
//! checks relationship targets and connections against the same grammar.

use anyhow::{Result, bail};

/// True for a USD identifier: a letter or underscore, then letters, digits, underscores.
fn identifier(s: &str) -> bool {
    s.chars().next().is_some_and(|c| c.is_alphabetic() || c == '_') && s.chars().all(|c| c.is_alphanumeric() || c == '_')
}

/// True when `name` is a well-formed (namespaced) property name: identifiers joined by ':'.
pub(crate) fn well_formed_name(name: &str) -> bool {
    name.split(':').all(identifier)
}

/// True when `path` is a well-formed absolute path: prim names of letters, digits and
/// underscores (not starting with a digit), optionally one namespaced property after a dot.
/// Targets and connections are checked before the stage is asked about them: the openusd
/// crate recursed without end composing a malformed binding target (`</World/Looks/Grey()`,
/// found by fuzzing) and overflowed the stack.
pub(crate) fn well_formed_path(path: &str) -> bool {
    let Some(rest) = path.strip_prefix('/') else { return false };
    if rest.is_empty() {
        return true;
    }
    let (prims, property) = match rest.split_once('.') {
        Some((a, b)) => (a, Some(b)),
        None => (rest, None),
    };
    prims.split('/').all(identifier) && property.is_none_or(well_formed_name)
}

/// True for a path as a `<...>` literal may hold: absolute or relative (`.`/`..` steps),
/// prim names, an optional namespaced property, optional `[target]` or `{variant=sel}` parts
/// left to the crate.
fn path_literal(p: &str) -> bool {
    if p.is_empty() {
        return true; // `<>`: an empty path, which USD allows as "none"
    }
    if p.contains(['{', '[']) {
        return !p.contains(['<', '>', '"', '(', ')', '\n']);
    }
    let body = p.strip_prefix('/').unwrap_or(p);
    if body.is_empty() {
        return p == "/";
    }
    let (prims, property) = match body.rsplit_once('.') {
        Some((a, b)) if !b.is_empty() && b != "." && !a.ends_with('.') && b.chars().next().is_some_and(|c| c != '/') => (a, Some(b)),
        _ => (body, None),
    };
    let prims_ok = prims.is_empty() || prims.split('/').all(|s| identifier(s) || s == ".." || s == ".");
    prims_ok && property.is_none_or(well_formed_name)
}

/// Checks prim names in `def`/`over`/`class` statements and every `<path>` literal.
pub fn check(text: &str) -> Result<()> {
    for (n, line) in text.lines().enumerate() {
        let code = line.split('#').next().unwrap_or("");
        let trimmed = code.trim_start();
        let statement =
            ["def ", "over ", "class "].iter().any(|k| trimmed.starts_with(k)) || ["def", "over", "class"].contains(&trimmed.trim_end());
        if statement {
            // The prim name is the first quoted string on the line.
            if let Some(start) = code.find('"') {
                let rest = &code[start + 1..];
                if let Some(end) = rest.find('"') {
                    let name = &rest[..end];
                    if !identifier(name) {
                        bail!("line {}: prim name \"{name}\" is not a valid identifier", n + 1);
                    }
                }
            }
        }
        let mut rest = code;
        while let Some(start) = rest.find('<') {
            let after = &rest[start + 1..];
            // `<` inside strings or asset paths (docs, UDIM tiles) is not a path literal.
            let quotes = rest[..start].matches('"').count() + rest[..start].matches('@').count();
            if quotes % 2 == 1 {
                rest = after;
                continue;
            }
            let Some(end) = after.find('>') else {
                bail!("line {}: path <{} is not closed", n + 1, after.trim_end());
            };
            let literal = &after[..end];
            if !path_literal(literal) {
                bail!("line {}: path <{literal}> is not a valid path", n + 1);
            }
            rest = &after[end + 1..];
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn malformed_paths_are_caught() {
        let ok = well_formed_path;
        assert!(ok("/World/Looks/Grey") && ok("/") && ok("/M/S.outputs:surface") && ok("/_a1/b_2"));
        for bad in ["/World/Looks/Grey()", "World", "/a//b", "/a/1b", "/a.b.c", "/a.", "", "/a b"] {
            assert!(!ok(bad), "{bad}");
        }
    }

    #[test]
    fn accepts_what_the_fixtures_use_and_rejects_what_fuzzing_found() {
        let good = "def Xform \"World\" {\n  rel material:binding = </World/Looks/Grey>\n  token outputs:surface.connect = </M/S.outputs:surface>\n  rel x = <../Sib.attr>\n  rel y = <>\n}\n";
        check(good).unwrap();
        for bad in [
            "def Shader \"Prin}ipled\" {}",
            "rel material:binding = </World/Looks/Grey()",
            "rel material:binding = </World/Looks/Grey()>",
            "token outputs:surface.connect = </World/Looks/Green/PreviewSurface.outputs:surfac def Shader>",
        ] {
            assert!(check(bad).is_err(), "{bad}");
        }
        // An asset path in a string may hold anything.
        check("asset inputs:file = @<UDIM>.png@\nstring doc = \"a <b> c\"").unwrap();
    }

    #[test]
    fn every_text_fixture_passes() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../fixtures");
        let mut n = 0;
        let mut stack = vec![root];
        while let Some(dir) = stack.pop() {
            for e in std::fs::read_dir(&dir).unwrap().flatten() {
                let p = e.path();
                if p.is_dir() {
                    stack.push(p);
                } else if p.extension().is_some_and(|x| x == "usda") && !p.to_string_lossy().contains("bad") {
                    check(&std::fs::read_to_string(&p).unwrap()).unwrap_or_else(|e| panic!("{}: {e}", p.display()));
                    n += 1;
                }
            }
        }
        assert!(n > 20);
    }
}
