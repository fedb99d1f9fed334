//! `otbake inspect`: what an archive holds, and whether it is valid.

use crate::key::hex;
use otbake_formats::header::{Header, HEADER_LEN};
use otbake_formats::write::aligned_copy;
use otbake_formats::{ArchiveKind, FormatError};

/// A human-readable description. The header is decoded on its own, so a file whose payload is
/// damaged is still described as far as possible.
pub fn describe(bytes: &[u8]) -> String {
    let mut s = format!("file size      {} bytes\n", bytes.len());
    let header = match Header::decode(bytes) {
        Ok(h) => h,
        Err(e) => return s + &format!("header         INVALID: {e}\n"),
    };
    s += &format!(
        "header         kind={} version={} rkyv_flags={:#b} payload={} bytes checksum={}\n",
        header.kind.name(),
        header.version,
        header.flags,
        header.payload_len,
        hex(&header.checksum)
    );
    let aligned = aligned_copy(bytes);
    match header.kind {
        ArchiveKind::Proxy => match otbake_formats::open::open_proxy(&aligned) {
            Ok(p) => {
                s += &format!(
                    "proxy          dim={} n={} leaf_size={} depth={} nodes={}\n",
                    p.dim,
                    p.n,
                    p.leaf_size,
                    p.depth,
                    p.node_boxes.len() / (2 * p.dim.to_native() as usize)
                );
                s += &format!("key            {}\n", hex(&p.key));
                s += &format!("settings       {}\n", &*p.description);
                s += &format!(
                    "sizes          positions={} B node_boxes={} B\n",
                    p.positions.len() * 4,
                    p.node_boxes.len() * 4
                );
            }
            Err(e) => s += &format!("payload        INVALID: {e}\n"),
        },
        ArchiveKind::Map => match otbake_formats::open::open_map(&aligned) {
            Ok(m) => {
                s += &format!(
                    "map            dim={} n={} depth={} composite={} mean_mass={}\n",
                    m.dim, m.n, m.depth, m.composite, m.mean_mass
                );
                s += &format!("key            {}\n", hex(&m.key));
                s += &format!("proxy key      {}\n", hex(&m.proxy_key));
                s += &format!("solver         {}\n", &*m.solver_report);
                s += &format!("transport cost {:.6e}\n", m.transport_cost.to_native());
                s += &format!(
                    "sizes          positions={} B colors={} B node_boxes={} B node_colors={} B\n",
                    m.positions.len() * 4,
                    m.colors.len() * 4,
                    m.node_boxes.len() * 4,
                    m.node_colors.len() * 4
                );
            }
            Err(e) => s += &format!("payload        INVALID: {e}\n"),
        },
    }
    s + &format!("payload offset {HEADER_LEN}\n")
}

/// Full validation (header, checksum, rkyv, consistency).
pub fn validate(bytes: &[u8]) -> Result<ArchiveKind, FormatError> {
    let aligned = aligned_copy(bytes);
    let kind = Header::decode(&aligned)?.kind;
    match kind {
        ArchiveKind::Proxy => otbake_formats::open::open_proxy(&aligned).map(|_| kind),
        ArchiveKind::Map => otbake_formats::open::open_map(&aligned).map(|_| kind),
    }
}
