//! Test support: a WGSL struct as naga lays it out, held against its `#[repr(C)]` Rust twin
//! (the record the pipelines upload byte for byte), so that neither side can drift alone.

/// One field of a Rust struct: its name, byte offset and byte size.
pub(crate) type Field = (&'static str, usize, usize);

/// The size of Rust struct `$ty` and the offset and size of each `$field` named (every
/// field its WGSL twin has; padding may be left out).
macro_rules! rust_layout {
    ($ty:ty { $($field:ident),* $(,)? }) => {{
        let zero: $ty = bytemuck::Zeroable::zeroed();
        let fields: Vec<$crate::wgsl_twin::Field> = vec![$((
            stringify!($field),
            std::mem::offset_of!($ty, $field),
            std::mem::size_of_val(&zero.$field),
        )),*];
        (std::mem::size_of::<$ty>(), fields)
    }};
}
pub(crate) use rust_layout;

/// Fails unless the struct `name` of the WGSL module `source` is as large as its Rust twin
/// (`twin`: size and fields), each of its members not named `_…` is a field of the twin at
/// the same offset and of the same size, and each field named is a member.
pub(crate) fn assert_twin(source: &str, name: &str, twin: (usize, Vec<Field>)) {
    let (size, fields) = twin;
    let module = naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string(source)));
    let ty = module
        .types
        .iter()
        .map(|(_, ty)| ty)
        .find(|ty| ty.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("the WGSL has no struct {name}"));
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        panic!("{name} is not a struct");
    };
    assert_eq!(
        *span as usize, size,
        "{name}: WGSL size against its Rust twin's"
    );
    for member in members {
        let member_name = member.name.as_deref().unwrap_or("");
        if member_name.starts_with('_') {
            continue;
        }
        let &(_, offset, bytes) = fields
            .iter()
            .find(|f| f.0 == member_name)
            .unwrap_or_else(|| panic!("{name}.{member_name}: not a field of the Rust twin"));
        let wgsl_bytes = module.types[member.ty].inner.size(module.to_ctx()) as usize;
        assert_eq!(
            (member.offset as usize, wgsl_bytes),
            (offset, bytes),
            "{name}.{member_name}: WGSL (offset, size) against its Rust twin's"
        );
    }
    for (field, _, _) in &fields {
        assert!(
            members.iter().any(|m| m.name.as_deref() == Some(field)),
            "{name}: the Rust twin's field {field} is not a WGSL member"
        );
    }
}
