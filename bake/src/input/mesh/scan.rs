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

/// Elements a face index can refer to: positions (`v`), texture coordinates (`vt`), normals (`vn`).
const KINDS: [(&str, &str, &str); 3] = [
    ("v", "vertex", "vertices"),
    ("vt", "texture coordinate", "texture coordinates"),
    ("vn", "normal", "normals"),
];

/// Checks the indices of one `f` line vertex (`v`, `v/vt`, `v//vn` or `v/vt/vn`) against the
/// elements of each kind: an error when one points at no element (tobj computes an element's
/// offset by a multiplication that overflows for a huge index, and reads a wrong element or
/// panics). Texture-coordinate and normal indices of a file with none are ignored, as tobj ignores
/// them. A part that is not a number is left to tobj to report. OBJ indices are 1-based; negative ones count back from the
/// last element defined so far.
fn check_index(
    path: &Path,
    line: usize,
    word: &str,
    defined: [u64; 3],
    total: [u64; 3],
) -> Result<(), MeshError> {
    for (k, part) in word.split('/').take(3).enumerate() {
        let Ok(i) = part.parse::<i64>() else {
            continue;
        };
        if k > 0 && total[k] == 0 {
            continue;
        }
        let ok = match i {
            0 => false,
            i if i > 0 => i as u64 <= total[k],
            i => i.unsigned_abs() <= defined[k],
        };
        if ok {
            continue;
        }
        let (keyword, one, many) = KINDS[k];
        let count = if i < 0 { defined[k] } else { total[k] };
        let exist = match count {
            0 => format!("no {one} is defined before it"),
            v => format!("only {v} {many} exist (1 to {v}, or -1 to -{v} counting back)"),
        };
        return Err(MeshError::Parse {
            path: path.to_path_buf(),
            reason: format!(
                "line {line}: a face refers to {one} index {i}, but {exist}; OBJ indices count from \
                 1, negative ones back from the last `{keyword}` line so far: fix the face or add the \
                 missing {many}"
            ),
        });
    }
    Ok(())
}

/// Scans OBJ text: see the module docs.
pub fn scan(path: &Path, text: &str) -> Result<Scan, MeshError> {
    let kind = |word: Option<&str>| KINDS.iter().position(|k| Some(k.0) == word);
    let mut total = [0u64; 3];
    for line in text.lines() {
        if let Some(k) = kind(line.split_whitespace().next()) {
            total[k] += 1;
        }
    }
    let mut s = Scan {
        vertices: total[0],
        ..Scan::default()
    };
    let mut defined = [0u64; 3];
    for (n, line) in text.lines().enumerate() {
        let mut words = line.split_whitespace();
        let first = words.next();
        if let Some(k) = kind(first) {
            defined[k] += 1;
            continue;
        }
        if first == Some("f") {
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

    /// Found by the fuzzer (`mesh` target, a dev build): a normal index of 2^63 − 1 made tobj's
    /// offset computation overflow (a panic with overflow checks, a wrong normal without). Texture
    /// coordinate and normal indices are checked like vertex indices when the file has any.
    #[test]
    fn texture_and_normal_indices_are_checked_when_the_file_has_them() {
        let head = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nvn 0 1 0\n";
        for (face, what) in [
            (
                "f 1//1 2//1 3//9223372036854775807",
                "normal index 9223372036854775807, but only 2 normals",
            ),
            (
                "f 1/2 2/1 3/1",
                "texture coordinate index 2, but only 1 texture coordinates",
            ),
            (
                "f 1/1/-3 2/1/1 3/1/1",
                "normal index -3, but only 2 normals",
            ),
        ] {
            let e = scan(Path::new("m.obj"), &format!("{head}{face}\n"))
                .unwrap_err()
                .to_string();
            assert!(e.contains("line 7:") && e.contains(what), "{e}");
        }
        assert!(scan(
            Path::new("m.obj"),
            &format!("{head}f 1/1/2 2/1/1 -1/1/-2\n")
        )
        .is_ok());
        // Without normals, normal indices mean nothing (tobj ignores them too).
        assert!(scan(
            Path::new("m.obj"),
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//7 2//7 3//7\n"
        )
        .is_ok());
    }
}
