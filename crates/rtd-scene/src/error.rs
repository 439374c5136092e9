use std::path::{Path, PathBuf};

/// A scene (or `--env` map) that could not be loaded. Every message is one line that names the
/// file first; I/O, glTF, OBJ and image errors are kept as the [`std::error::Error::source`].
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read: it is missing (`PATH: no such file`), unreadable or a directory.
    #[error("{path}: {}", io_reason(.source))]
    Io {
        /// The file that could not be read.
        path: PathBuf,
        /// The underlying I/O error.
        source: std::io::Error,
    },
    /// The file's extension names no scene format rtd reads.
    #[error("{path}: unknown scene format (use .gltf, .glb or .obj)")]
    UnknownFormat {
        /// The file concerned.
        path: PathBuf,
    },
    /// The glTF JSON or GLB container could not be parsed or failed validation, or its buffers
    /// or images could not be loaded.
    #[error("{path}: {stage}: {}", one_line(.source))]
    Gltf {
        /// The glTF file.
        path: PathBuf,
        /// What was being done: `malformed glTF`, `invalid glTF` or `cannot load buffers`.
        stage: &'static str,
        /// The glTF crate's error.
        source: gltf::Error,
    },
    /// One of a glTF file's images could not be read or decoded: the message names the image
    /// (index and URI or name) and, when the decoder's memory limit refused it, that limit.
    #[error("{path}: cannot load image {image}: {}{}", one_line(.source), limit_hint(.source))]
    GltfImage {
        /// The glTF file.
        path: PathBuf,
        /// The image: its index, then its URI, name or buffer view, e.g. `0 ("wood.png")`.
        image: String,
        /// The glTF crate's error.
        source: gltf::Error,
    },
    /// The glTF file lists, in `extensionsRequired`, an extension rtd does not implement.
    #[error("{path}: required extension {extension} is not supported (rtd supports: {})", .supported.join(", "))]
    UnsupportedGltfExtension {
        /// The glTF file.
        path: PathBuf,
        /// The required extension's name.
        extension: String,
        /// The extensions rtd implements ([`crate::SUPPORTED_GLTF_EXTENSIONS`]).
        supported: &'static [&'static str],
    },
    /// A glTF buffer view runs past the end of its buffer.
    #[error(
        "{path}: buffer view {view} (bytes {offset}..{}) runs past the end of buffer {buffer} ({buffer_length} bytes)",
        view_end(.offset, .length)
    )]
    BufferView {
        /// The glTF file.
        path: PathBuf,
        /// Index of the buffer view.
        view: usize,
        /// The view's byte offset into its buffer.
        offset: usize,
        /// The view's length in bytes.
        length: usize,
        /// Index of the buffer the view reads.
        buffer: usize,
        /// The buffer's declared length in bytes.
        buffer_length: usize,
    },
    /// An accessor that a triangle mesh reads is corrupt: its data runs outside its buffer view,
    /// it has the wrong type, or its indices name vertices that do not exist.
    #[error("{path}: mesh {mesh}{}, accessor {accessor}: {problem}", name_suffix(.mesh_name))]
    Accessor {
        /// The glTF file.
        path: PathBuf,
        /// Index of the mesh in the file.
        mesh: usize,
        /// The mesh's name, if the file gives one.
        mesh_name: Option<String>,
        /// Index of the accessor in the file.
        accessor: usize,
        /// What is wrong with the accessor.
        problem: Box<AccessorProblem>,
    },
    /// The OBJ file could not be parsed.
    #[error("{path}: cannot load OBJ: {source}")]
    Obj {
        /// The OBJ file.
        path: PathBuf,
        /// The OBJ parser's error.
        source: tobj::LoadError,
    },
    /// An environment map could not be read; the image error names the file.
    #[error("{source}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// The image reader's error.
        source: rtd_image::ImageError,
    },
    /// Malformed content (or a malformed argument) described in one line.
    #[error("{path}: {message}")]
    Invalid {
        /// The file (or argument) concerned.
        path: PathBuf,
        /// What is wrong with it, in one line.
        message: String,
    },
}

impl SceneError {
    /// A [`SceneError::Invalid`] for `path`; line breaks in `message` become spaces.
    pub fn new(path: &Path, message: impl ToString) -> Self {
        SceneError::Invalid { path: path.to_path_buf(), message: one_line(&message.to_string()) }
    }

    /// A [`SceneError::Io`] for `path`.
    pub fn io(path: &Path, source: std::io::Error) -> Self {
        SceneError::Io { path: path.to_path_buf(), source }
    }

    /// The file (or `--env` argument) that failed to load.
    pub fn path(&self) -> &Path {
        match self {
            SceneError::Io { path, .. }
            | SceneError::UnknownFormat { path }
            | SceneError::Gltf { path, .. }
            | SceneError::GltfImage { path, .. }
            | SceneError::UnsupportedGltfExtension { path, .. }
            | SceneError::BufferView { path, .. }
            | SceneError::Accessor { path, .. }
            | SceneError::Obj { path, .. }
            | SceneError::Image { path, .. }
            | SceneError::Invalid { path, .. } => path,
        }
    }
}

/// What is wrong with a glTF accessor (see [`SceneError::Accessor`]).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum AccessorProblem {
    /// The accessor, or its sparse substitution, has a count of zero.
    #[error("{what} count is 0")]
    ZeroCount {
        /// `element` for the accessor's own count, `sparse` for its sparse count.
        what: &'static str,
    },
    /// Elements (or sparse indices or values) run past the end of their buffer view.
    #[error(
        "{count} {what} of {element_size} bytes{} run past the end of buffer view {view} ({view_length} bytes)",
        layout(.offset, .stride, .element_size)
    )]
    PastViewEnd {
        /// What runs past: `elements`, `sparse indices` or `sparse values`.
        what: &'static str,
        /// How many there are.
        count: usize,
        /// Bytes per element.
        element_size: usize,
        /// Byte offset of the first element inside the view.
        offset: usize,
        /// Bytes from one element to the next.
        stride: usize,
        /// Index of the buffer view.
        view: usize,
        /// The view's length in bytes.
        view_length: usize,
    },
    /// The buffer view's byte stride is smaller than one element, so elements would overlap.
    #[error("buffer view {view} has a byte stride of {stride}, less than one {element_size}-byte element")]
    StrideTooSmall {
        /// Index of the buffer view.
        view: usize,
        /// The view's byte stride.
        stride: usize,
        /// Bytes per element.
        element_size: usize,
    },
    /// An attribute (or the indices) has an element type rtd cannot read it as.
    #[error("{semantic} is {found}; rtd reads {expected}")]
    WrongType {
        /// The attribute's name (`POSITION`, `NORMAL`, …) or `indices`.
        semantic: String,
        /// The accessor's element type, e.g. `VEC2 of u16`.
        found: String,
        /// The types rtd reads, e.g. `VEC3 of f32`.
        expected: String,
    },
    /// An attribute's count differs from the POSITION accessor's.
    #[error("{semantic} has {count} elements but POSITION has {vertex_count}")]
    CountMismatch {
        /// The attribute's name.
        semantic: String,
        /// The attribute's element count.
        count: usize,
        /// The POSITION accessor's element count.
        vertex_count: usize,
    },
    /// An index names a vertex past the end of the POSITION accessor.
    #[error("index {index} is out of range ({vertex_count} vertices)")]
    IndexOutOfRange {
        /// The offending index value.
        index: u32,
        /// The number of vertices (POSITION's count).
        vertex_count: usize,
    },
}

/// `no such file` for a missing file, else the I/O error's own text.
fn io_reason(e: &std::io::Error) -> String {
    match e.kind() {
        std::io::ErrorKind::NotFound => "no such file".to_string(),
        _ => one_line(&e.to_string()),
    }
}

/// `s` with line breaks turned into spaces, so that every message stays on one line.
fn one_line(s: &impl ToString) -> String {
    s.to_string().replace('\n', " ")
}

/// Bytes the glTF crate's image decoder may allocate for one image: the `image` crate's default
/// limit, which it decodes under.
const GLTF_IMAGE_LIMIT_MIB: u64 = 512;

/// For an image the decoder's memory limit refused, what the limit is and what passes it.
fn limit_hint(e: &gltf::Error) -> String {
    match e {
        gltf::Error::Image(image::ImageError::Limits(_)) => format!(
            " (the image decoder allows at most {GLTF_IMAGE_LIMIT_MIB} MiB an image, 11585x11585 at 8-bit RGBA)"
        ),
        _ => String::new(),
    }
}

/// ` ("NAME")` for a named mesh, nothing for an unnamed one.
fn name_suffix(name: &Option<String>) -> String {
    name.as_ref().map(|n| format!(" ({n:?})")).unwrap_or_default()
}

/// One past the last byte of a buffer view, without overflow.
fn view_end(offset: &usize, length: &usize) -> u128 {
    *offset as u128 + *length as u128
}

/// ` at offset O`, ` with stride S` or both, where the elements are not packed from the view's start.
fn layout(offset: &usize, stride: &usize, element_size: &usize) -> String {
    match (*offset, *stride == *element_size) {
        (0, true) => String::new(),
        (o, true) => format!(" at offset {o}"),
        (0, false) => format!(" with stride {stride}"),
        (o, false) => format!(" at offset {o} with stride {stride}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_file_reads_no_such_file_and_keeps_its_source() {
        let e = SceneError::io(Path::new("gone.gltf"), std::io::Error::from(std::io::ErrorKind::NotFound));
        assert_eq!(e.to_string(), "gone.gltf: no such file");
        assert_eq!(e.path(), Path::new("gone.gltf"));
        let source = std::error::Error::source(&e).expect("the io::Error is kept");
        assert!(source.downcast_ref::<std::io::Error>().is_some());
    }

    #[test]
    fn an_image_over_the_decoders_memory_limit_says_what_the_limit_is() {
        use image::error::{LimitError, LimitErrorKind};
        let limits = image::ImageError::Limits(LimitError::from_kind(LimitErrorKind::InsufficientMemory));
        let e = SceneError::GltfImage {
            path: PathBuf::from("big.gltf"),
            image: "0 (\"big.png\")".into(),
            source: gltf::Error::Image(limits),
        };
        assert_eq!(
            e.to_string(),
            "big.gltf: cannot load image 0 (\"big.png\"): Memory limit exceeded (the image decoder allows at most \
             512 MiB an image, 11585x11585 at 8-bit RGBA)"
        );
        assert_eq!(e.path(), Path::new("big.gltf"));
        // Other image errors get no hint.
        let e = SceneError::GltfImage {
            path: PathBuf::from("a.gltf"),
            image: "1".into(),
            source: gltf::Error::MissingBlob,
        };
        assert!(!e.to_string().contains("MiB"), "{e}");
    }

    #[test]
    fn messages_stay_on_one_line_and_name_the_file_first() {
        let e = SceneError::new(Path::new("a.obj"), "two\nlines");
        assert_eq!(e.to_string(), "a.obj: two lines");
        let e = SceneError::Accessor {
            path: PathBuf::from("scene.gltf"),
            mesh: 0,
            mesh_name: Some("Cube".into()),
            accessor: 2,
            problem: Box::new(AccessorProblem::PastViewEnd {
                what: "elements",
                count: 1_000_000_000,
                element_size: 12,
                offset: 0,
                stride: 12,
                view: 0,
                view_length: 48,
            }),
        };
        assert_eq!(
            e.to_string(),
            "scene.gltf: mesh 0 (\"Cube\"), accessor 2: 1000000000 elements of 12 bytes run past the end of \
             buffer view 0 (48 bytes)"
        );
        let p = AccessorProblem::PastViewEnd {
            what: "sparse values",
            count: 3,
            element_size: 4,
            offset: 8,
            stride: 16,
            view: 1,
            view_length: 40,
        };
        assert_eq!(
            p.to_string(),
            "3 sparse values of 4 bytes at offset 8 with stride 16 run past the end of buffer view 1 (40 bytes)"
        );
    }
}
