//! One pass over an OBJ file's text before tobj parses it: counts for the memory estimate, face
//! indices checked against the vertices with the line that holds them, and faces of fewer than
//! three vertices found (they bound no area: they are dropped, and the bake report says so).

use super::MeshError;
use std::path::Path;

/// What the scan found.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Scan {
    /// `v` lines.
    pub vertices: u64,
    /// Triangles the faces fan into (`k − 2` for a face of `k` vertices).
    pub triangles: u64,
    /// 1-based lines of faces with one or two vertices (dropped before parsing).
    pub short_faces: Vec<usize>,
}

/// The position index of one `f` line vertex (`v`, `v/vt`, `v//vn` or `v/vt/vn`): `Ok(None)` when
/// it is not a number (tobj reports that), an error when it points at no vertex. OBJ indices are
/// 1-based; negative ones count back from the last vertex defined so far.
fn check_index(
    path: &Path,
    line: usize,
    word: &str,
    defined: u64,
    total: u64,
) -> Result<(), MeshError> {
    let Ok(i) = word.split('/').next().unwrap_or("").parse::<i64>() else {
        return Ok(());
    };
    let ok = match i {
        0 => false,
        i if i > 0 => i as u64 <= total,
        i => i.unsigned_abs() <= defined,
    };
    if ok {
        return Ok(());
    }
    let vertices = if i < 0 { defined } else { total };
    let exist = match vertices {
        0 => "no vertex is defined before it".to_string(),
        v => format!("only {v} vertices exist (1 to {v}, or -1 to -{v} counting back)"),
    };
    Err(MeshError::Parse {
        path: path.to_path_buf(),
        reason: format!(
            "line {line}: a face refers to vertex index {i}, but {exist}; OBJ indices count from 1, \
             negative ones back from the last `v` line so far: fix the face or add the missing vertices"
        ),
    })
}

/// Scans OBJ text: see the module docs.
pub fn scan(path: &Path, text: &str) -> Result<Scan, MeshError> {
    let total = text
        .lines()
        .filter(|l| l.split_whitespace().next() == Some("v"))
        .count() as u64;
    let mut s = Scan {
        vertices: total,
        ..Scan::default()
    };
    let mut defined = 0u64;
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        match words.next() {
            Some("v") => defined += 1,
            Some("f") => {
                let mut corners = 0u64;
                for w in words.take_while(|w| !w.starts_with('#')) {
                    check_index(path, n + 1, w, defined, total)?;
                    corners += 1;
                }
                if corners < 3 {
                    s.short_faces.push(n + 1);
                } else {
                    s.triangles += corners - 2;
                }
            }
            _ => {}
        }
    }
    Ok(s)
}

/// `text` without the lines `drop` lists (1-based, ascending), each replaced by an empty line so
/// that tobj's and our line numbers stay the same.
pub fn without_lines(text: &str, drop: &[usize]) -> String {
    let mut out = String::with_capacity(text.len());
    let mut next = drop.iter().peekable();
    for (n, line) in text.split_inclusive('\n').enumerate() {
        if next.peek() == Some(&&(n + 1)) {
            next.next();
            if line.ends_with('\n') {
                out.push('\n');
            }
        } else {
            out.push_str(line);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn counts_and_short_faces() {
        let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2\nf 1/1 2/2 3/3 4/4 # quad\nf -1 -2 -3\n";
        let s = scan(Path::new("m.obj"), text).unwrap();
        assert_eq!((s.vertices, s.triangles), (4, 4));
        assert_eq!(s.short_faces, vec![6]);
        assert_eq!(without_lines(text, &s.short_faces).lines().nth(5), Some(""));
    }

    #[test]
    fn an_index_out_of_range_names_the_line_and_the_index() {
        for (face, index) in [("f 1 2 9", "9"), ("f 0 1 2", "0"), ("f 1 2 -7", "-7")] {
            let text = format!("v 0 0 0\nv 1 0 0\nv 0 1 0\n# a comment\n{face}\n");
            let e = scan(Path::new("m.obj"), &text).unwrap_err().to_string();
            assert!(e.contains("m.obj") && e.contains("line 5:"), "{e}");
            assert!(e.contains(&format!("index {index}")), "{e}");
            assert!(e.contains("3 vertices"), "{e}");
        }
    }
}
