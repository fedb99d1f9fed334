//! `otbake inspect`: what an archive holds, and whether it is valid.

use crate::pipeline::key::hex;
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
                    "proxy          dim={} n={} leaf_size={} depth={} nodes={} wrap={}\n",
                    p.dim,
                    p.n,
                    p.leaf_size,
                    p.depth,
                    p.node_boxes.len() / (2 * p.dim.to_native() as usize),
                    wrap_name(p.wrap.to_native())
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
        ArchiveKind::Map => match otbake_formats::view::MapView::open(&aligned) {
            Ok(view) => {
                let m = view.archived();
                s += &format!(
                    "map            dim={} n={} depth={} composite={} mean_mass={} wrap={}\n",
                    m.dim,
                    m.n,
                    m.depth,
                    m.composite,
                    m.mean_mass,
                    wrap_name(m.wrap.to_native())
                );
                s += &format!("key            {}\n", hex(&m.key));
                s += &format!("proxy key      {}\n", hex(&m.proxy_key));
                s += &format!("solver         {}\n", &*m.solver_report);
                s += &format!("transport cost {:.6e}\n", m.transport_cost.to_native());
                s += &format!("storage        {}\n", describe_storage(&view.storage()));
                s += &format!(
                    "sizes          positions={} B colors={} B node_boxes={} B node_colors={} B spacings={} B\n",
                    m.positions.len(),
                    m.colors.len(),
                    m.node_boxes.len(),
                    m.node_colors.len() * 4,
                    m.spacings.len() + m.node_spacings.len()
                );
                let d = view.dim();
                let pe = view.max_position_error();
                let ce = view.color_error();
                s += &format!(
                    "error bound    position {} (largest per axis), color {}\n",
                    list(&pe[..d]),
                    if view.has_color() {
                        list(&ce)
                    } else {
                        "none stored".into()
                    }
                );
            }
            Err(e) => s += &format!("payload        INVALID: {e}\n"),
        },
    }
    s + &format!("payload offset {HEADER_LEN}\n")
}

/// `positions=u8 node_boxes=u16 colors=u8 node_colors=yes spacings=no`.
pub fn describe_storage(s: &otbake_formats::storage::Storage) -> String {
    let yes = |b: bool| if b { "yes" } else { "no" };
    format!(
        "positions={} node_boxes={} colors={} node_colors={} spacings={}",
        s.positions.name(),
        s.node_boxes.name(),
        s.colors.map_or("none", |p| p.name()),
        yes(s.node_colors),
        yes(s.spacings)
    )
}

fn list(v: &[f32]) -> String {
    let parts: Vec<String> = v.iter().map(|x| format!("{x:.3e}")).collect();
    format!("[{}]", parts.join(", "))
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

/// The manifest's name of a (validated) wrap code; periodic maps store lifts (see `Wrap`).
fn wrap_name(code: u32) -> &'static str {
    match otbake_formats::Wrap::from_code(code) {
        Some(otbake_formats::Wrap::Periodic) => "periodic (positions are lifts p+δ)",
        Some(otbake_formats::Wrap::Clamp) => "clamp",
        None => "unknown",
    }
}
