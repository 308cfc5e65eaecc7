//! Refuse an output path that names one of the command's inputs (issue 38, F9): the same file
//! by device and inode, so a hard link, a symlink or another spelling of the input's path is
//! caught as well as the path itself. Every command that writes a file checks this before it
//! opens anything for writing; the error exits 1 and names both paths.

use anyhow::{bail, Result};
use std::os::unix::fs::MetadataExt;
use std::path::Path;

/// `outputs` and `inputs` as (option, path): `("-o", out)`, `("--rig", rig)`. An output that
/// does not exist yet cannot be an input; nor can an input that does not exist (the command
/// reports that itself).
pub fn refuse_output_naming_input(
    outputs: &[(&str, &Path)],
    inputs: &[(&str, &Path)],
) -> Result<()> {
    for (oflag, out) in outputs {
        let Ok(o) = std::fs::metadata(out) else {
            continue;
        };
        for (iflag, inp) in inputs {
            let Ok(i) = std::fs::metadata(inp) else {
                continue;
            };
            if (o.dev(), o.ino()) == (i.dev(), i.ino()) {
                let how = if same_path(out, inp) {
                    "the same path"
                } else {
                    "another name (hard link or symlink) for the same file"
                };
                bail!(
                    "{oflag} {}: that is the input {}{} ({how}, inode {}); writing it would \
                     destroy the input: write to another path",
                    out.display(),
                    if iflag.is_empty() {
                        String::new()
                    } else {
                        format!("{iflag} ")
                    },
                    inp.display(),
                    o.ino()
                );
            }
        }
    }
    Ok(())
}

fn same_path(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(x), Ok(y)) => x == y,
        _ => a == b,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_hard_link_of_an_input_is_refused_naming_both() {
        let d = tempfile::tempdir().unwrap();
        let (inp, link, other) = (d.path().join("in"), d.path().join("l"), d.path().join("o"));
        std::fs::write(&inp, b"x").unwrap();
        std::fs::hard_link(&inp, &link).unwrap();
        std::fs::write(&other, b"x").unwrap();
        let e = refuse_output_naming_input(&[("-o", &link)], &[("", &inp)])
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("hard link") && e.contains("in") && e.contains("-o"),
            "{e}"
        );
        let e = refuse_output_naming_input(&[("-o", &inp)], &[("--rig", &other), ("", &inp)])
            .unwrap_err()
            .to_string();
        assert!(e.contains("the same path"), "{e}");
        let fresh = d.path().join("new");
        assert!(
            refuse_output_naming_input(&[("-o", &other), ("-o", &fresh)], &[("", &inp)]).is_ok()
        );
    }
}
