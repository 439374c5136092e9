//! Structural checks on glTF buffer views and on the accessors a triangle primitive reads.
//!
//! The gltf crate's readers return `None` for an accessor whose data runs past its buffer view
//! and assert on element types they do not expect, so without these checks a corrupt mesh would
//! vanish from the render (or panic). Each check mirrors the byte range the reader takes:
//! `offset + stride·(count − 1) + element size` inside the view, with the stride the view gives or
//! the element size when it gives none.

use std::path::Path;

use gltf::accessor::{DataType, Dimensions};
use gltf::mesh::Semantic;

use crate::{AccessorProblem, SceneError};

/// Component types read as floats.
const FLOAT: &[DataType] = &[DataType::F32];
/// Component types `TEXCOORD_n` (and `COLOR_0`) may have: float or normalised unsigned integers.
const TEXCOORD_TYPES: &[DataType] = &[DataType::F32, DataType::U8, DataType::U16];
/// Component types indices may have.
const INDEX_TYPES: &[DataType] = &[DataType::U8, DataType::U16, DataType::U32];

/// The file and mesh an accessor is read for, to name them in errors.
#[derive(Debug, Clone, Copy)]
pub(crate) struct MeshSite<'a> {
    /// The glTF file.
    pub path: &'a Path,
    /// Index of the mesh in the file.
    pub index: usize,
    /// The mesh's name, if any.
    pub name: Option<&'a str>,
}

impl MeshSite<'_> {
    /// A [`SceneError::Accessor`] for accessor `accessor` of this mesh.
    pub fn error(&self, accessor: usize, problem: AccessorProblem) -> SceneError {
        SceneError::Accessor {
            path: self.path.to_path_buf(),
            mesh: self.index,
            mesh_name: self.name.map(str::to_string),
            accessor,
            problem: Box::new(problem),
        }
    }
}

/// Refuses a document with a buffer view that runs past the end of its buffer (the image
/// importer would index out of bounds on one).
pub(crate) fn check_buffer_views(document: &gltf::Document, path: &Path) -> Result<(), SceneError> {
    for view in document.views() {
        let buffer = view.buffer();
        if view.offset() as u128 + view.length() as u128 > buffer.length() as u128 {
            return Err(SceneError::BufferView {
                path: path.to_path_buf(),
                view: view.index(),
                offset: view.offset(),
                length: view.length(),
                buffer: buffer.index(),
                buffer_length: buffer.length(),
            });
        }
    }
    Ok(())
}

/// Checks every accessor of a triangle primitive: first that each attribute and the indices lie
/// inside their buffer views, then that the ones rtd reads (POSITION, NORMAL, TANGENT,
/// TEXCOORD_0 and _1, COLOR_0, indices) have an element type it reads and, for attributes, POSITION's count.
pub(crate) fn check_primitive(prim: &gltf::Primitive, site: MeshSite) -> Result<(), SceneError> {
    for (_, accessor) in prim.attributes() {
        check_layout(&accessor, site)?;
    }
    if let Some(indices) = prim.indices() {
        check_layout(&indices, site)?;
    }
    let vertex_count = prim.get(&Semantic::Positions).map(|a| a.count());
    for (semantic, accessor) in prim.attributes() {
        // COLOR_0 may be RGB or RGBA; the alpha is not read.
        let readable = match (&semantic, accessor.dimensions()) {
            (Semantic::Colors(0), Dimensions::Vec4) => Some((Dimensions::Vec4, TEXCOORD_TYPES)),
            (Semantic::Colors(0), _) => Some((Dimensions::Vec3, TEXCOORD_TYPES)),
            _ => attribute_types(&semantic),
        };
        let Some(readable) = readable else {
            continue;
        };
        check_type(&accessor, &semantic.to_string(), readable, site)?;
        let count = accessor.count();
        if let Some(vertex_count) = vertex_count.filter(|&n| n != count) {
            let problem = AccessorProblem::CountMismatch { semantic: semantic.to_string(), count, vertex_count };
            return Err(site.error(accessor.index(), problem));
        }
    }
    if let Some(indices) = prim.indices() {
        check_type(&indices, "indices", (Dimensions::Scalar, INDEX_TYPES), site)?;
    }
    Ok(())
}

/// Refuses an index that names a vertex past the end of POSITION. `indices` are the values read
/// from the primitive's index accessor; a primitive without one has nothing to check.
pub(crate) fn check_indices(
    prim: &gltf::Primitive,
    indices: &[u32],
    vertex_count: usize,
    site: MeshSite,
) -> Result<(), SceneError> {
    let Some(accessor) = prim.indices() else {
        return Ok(());
    };
    match indices.iter().find(|&&i| i as usize >= vertex_count) {
        Some(&index) => Err(site.error(accessor.index(), AccessorProblem::IndexOutOfRange { index, vertex_count })),
        None => Ok(()),
    }
}

/// The element types rtd reads an attribute as (dimensions, component types), or `None` for an
/// attribute it does not read.
fn attribute_types(semantic: &Semantic) -> Option<(Dimensions, &'static [DataType])> {
    match semantic {
        Semantic::Positions | Semantic::Normals => Some((Dimensions::Vec3, FLOAT)),
        Semantic::Tangents => Some((Dimensions::Vec4, FLOAT)),
        Semantic::TexCoords(0 | 1) => Some((Dimensions::Vec2, TEXCOORD_TYPES)),
        _ => None,
    }
}

/// Refuses an accessor whose element type is not one of `readable`.
fn check_type(
    accessor: &gltf::Accessor,
    semantic: &str,
    readable: (Dimensions, &'static [DataType]),
    site: MeshSite,
) -> Result<(), SceneError> {
    let (dimensions, data_types) = readable;
    if accessor.dimensions() == dimensions && data_types.contains(&accessor.data_type()) {
        return Ok(());
    }
    let names: Vec<&str> = data_types.iter().map(|&t| data_type_name(t)).collect();
    let problem = AccessorProblem::WrongType {
        semantic: semantic.to_string(),
        found: format!("{} of {}", dimensions_name(accessor.dimensions()), data_type_name(accessor.data_type())),
        expected: format!("{} of {}", dimensions_name(dimensions), names.join(" or ")),
    };
    Err(site.error(accessor.index(), problem))
}

/// Checks that an accessor's elements, and its sparse indices and values, lie inside their views.
fn check_layout(accessor: &gltf::Accessor, site: MeshSite) -> Result<(), SceneError> {
    let err = |problem| site.error(accessor.index(), problem);
    let count = accessor.count();
    if count == 0 {
        return Err(err(AccessorProblem::ZeroCount { what: "element" }));
    }
    if let Some(view) = accessor.view() {
        check_span(&view, accessor.offset(), count, accessor.size(), "elements").map_err(err)?;
    }
    if let Some(sparse) = accessor.sparse() {
        let sparse_count = sparse.count();
        if sparse_count == 0 {
            return Err(err(AccessorProblem::ZeroCount { what: "sparse" }));
        }
        let indices = sparse.indices();
        let index_size = indices.index_type().size();
        check_span(&indices.view(), indices.offset(), sparse_count, index_size, "sparse indices").map_err(err)?;
        let values = sparse.values();
        check_span(&values.view(), values.offset(), sparse_count, accessor.size(), "sparse values").map_err(err)?;
    }
    Ok(())
}

/// Checks that `count` (at least one) elements of `element_size` bytes, the first at byte
/// `offset`, fit inside `view` with the view's stride.
fn check_span(
    view: &gltf::buffer::View,
    offset: usize,
    count: usize,
    element_size: usize,
    what: &'static str,
) -> Result<(), AccessorProblem> {
    let stride = view.stride().unwrap_or(element_size);
    if stride < element_size {
        return Err(AccessorProblem::StrideTooSmall { view: view.index(), stride, element_size });
    }
    let end = offset as u128 + stride as u128 * (count as u128 - 1) + element_size as u128;
    if end > view.length() as u128 {
        return Err(AccessorProblem::PastViewEnd {
            what,
            count,
            element_size,
            offset,
            stride,
            view: view.index(),
            view_length: view.length(),
        });
    }
    Ok(())
}

/// The glTF name of an element's shape.
fn dimensions_name(d: Dimensions) -> &'static str {
    match d {
        Dimensions::Scalar => "SCALAR",
        Dimensions::Vec2 => "VEC2",
        Dimensions::Vec3 => "VEC3",
        Dimensions::Vec4 => "VEC4",
        Dimensions::Mat2 => "MAT2",
        Dimensions::Mat3 => "MAT3",
        Dimensions::Mat4 => "MAT4",
    }
}

/// The Rust name of a component type.
fn data_type_name(t: DataType) -> &'static str {
    match t {
        DataType::I8 => "i8",
        DataType::U8 => "u8",
        DataType::I16 => "i16",
        DataType::U16 => "u16",
        DataType::U32 => "u32",
        DataType::F32 => "f32",
    }
}
