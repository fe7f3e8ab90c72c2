//! glTF 2.0 loader: `.gltf` (external `.bin` files or base64 data URIs) and `.glb`.
//!
//! What is loaded:
//!
//! * The node hierarchy of the default scene (else scene 0, else every node that is nobody's
//!   child), with TRS or matrix transforms. Each glTF node becomes one scene node per path that
//!   reaches it: a node listed as the child of two parents (a shared subgraph, which the
//!   glTF 2.0 specification does not allow but files do contain) loads as two copies of its
//!   subtree, sharing their meshes. The copies count against [`LoadOptions::max_nodes`], so
//!   a small file cannot ask for exponentially many, and what each copy repeats (its name,
//!   its camera's name, the curves animating it) against
//!   [`LoadOptions::max_decoded_bytes`], as every accessor decoded does (once per primitive
//!   or animation sampler that names it). A glTF mesh with one drawable primitive is drawn
//!   by the node itself; with several, by one child node per primitive. Each glTF mesh is
//!   converted once (a scene mesh per drawable primitive), for every node that draws it, so
//!   glTF instancing stays instancing in the mesh store.
//! * Primitives of mode `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` (strips and fans are
//!   converted to triangle lists with the winding kept); points and lines are skipped and
//!   counted in a warning. Attributes `POSITION`, `NORMAL`, `TEXCOORD_0` (float, or integer
//!   types as `KHR_mesh_quantization` allows), indices of u8/u16/u32 or none, sparse accessors.
//! * Materials: `pbrMetallicRoughness.baseColorFactor` and `baseColorTexture` (PNG or JPEG,
//!   decoded to RGBA8 with the `image` crate), `alphaMode` (`OPAQUE`, `MASK`, `BLEND`) and
//!   `alphaCutoff` (default 0.5) as [`AlphaMode`], `emissiveFactor` as
//!   [`Material::emissive`].
//! * Perspective and orthographic cameras, as [`SceneCamera`]s on their nodes.
//!
//! * Animations of node translation, rotation and scale (STEP, LINEAR, CUBICSPLINE), as
//!   [`Scene::animations`]; skinned nodes and morph targets are drawn in the bind pose, with a
//!   warning (see the `animation` submodule).
//!
//! The other material channels are ignored.
//!
//! External files (buffer and image URIs; glTF 2.0 specification, sections "URIs", "Buffers
//! and Buffer Views" and "Images") are read under the rules of [`crate::assets`]: inside the glTF file's folder (or an allowed root), regular files
//! only, each read once and no further than needed, within a total. A buffer is read only when
//! an accessor or image that the scene uses needs it, and no more than its `byteLength`.
//!
//! Errors ([`Error::Load`], naming the file and the problem): unreadable file, wrong magic,
//! truncated GLB, invalid JSON, missing or short buffers that the scene uses, accessors
//! reading past their buffer views, indices out of range, NaN/infinite transforms, a cycle in the
//! node graph (a node its own ancestor), more nodes than [`LoadOptions::max_nodes`] once
//! shared subgraphs are expanded, more decoded and copied data than
//! [`LoadOptions::max_decoded_bytes`], a required extension this loader does
//! not support, a buffer or image URI that the rules above refuse (outside the folder, not a
//! regular file, over the total).
//! Warnings (in [`Scene::warnings`], the scene still loads): a missing or undecodable
//! texture (the material keeps its base color factor), an unknown `alphaMode` (opaque) or an
//! `alphaCutoff` below 0 (0.5), skipped point/line primitives, used but
//! not required unknown extensions, unusable cameras, bad animation channels (skipped), skins
//! and morph targets (drawn in the bind pose).
//!
//! The loader does its own bounds-checked parsing of the GLB container, buffers and accessors
//! on top of `gltf::json` (serde structs), so no input makes it panic.

use std::cell::{Cell, OnceCell};
use std::collections::HashMap;
use std::path::Path;
use std::rc::Rc;
use std::sync::Arc;

use glam::{Mat4, Quat, Vec2, Vec3};
use gltf::json;
use json::accessor::{ComponentType, Type};
use json::mesh::{Mode, Semantic};
use json::validation::Checked;

use crate::assets::{AssetError, AssetReader};

mod animation;
mod data;
mod materials;
use crate::{
    AlphaMode, Error, LoadOptions, Material, MaterialId, Mesh, MeshId, NodeDesc, NodeId, Projection, Result, Scene,
    SceneCamera, Texture, Transform, DEFAULT_ALPHA_CUTOFF,
};
use data::*;
pub(crate) use materials::decode_for_load;

/// glTF extensions this loader honours, so a file may list them in `extensionsRequired`.
pub const SUPPORTED_EXTENSIONS: &[&str] = &["KHR_mesh_quantization"];

/// Far plane used for a perspective camera without `zfar` (an infinite projection in glTF):
/// `max(DEFAULT_FAR, 1e4 * znear)`.
pub const DEFAULT_FAR: f32 = 1.0e4;

/// Aspect ratio used for a perspective camera without `aspectRatio`.
pub const DEFAULT_ASPECT: f32 = 1.0;

/// Loads a `.gltf` or `.glb` file; external buffers and images are found next to it, with the
/// default [`LoadOptions`] (files inside its folder only).
///
/// The returned scene's world transforms are not yet propagated (call
/// [`Scene::update_transforms`], or use [`crate::load`], which does).
pub fn load_gltf(path: &Path) -> Result<Scene> {
    load_gltf_with(path, &LoadOptions::default())
}

/// [`load_gltf`] with options: other folders external files may come from, a read cap.
pub fn load_gltf_with(path: &Path, options: &LoadOptions) -> Result<Scene> {
    let assets = AssetReader::new(path, options).map_err(|e| Error::load(path, e))?;
    let bytes = assets.read_main().map_err(|e| Error::load(path, e))?;
    load_with_reader(&bytes, path, &assets, options)
}

/// Loads glTF or GLB from memory. `path` names the file in messages, decides whether the bytes
/// must be GLB (extension `.glb`), and its folder resolves relative URIs (under the default
/// [`LoadOptions`]).
pub fn load_gltf_bytes(bytes: &[u8], path: &Path) -> Result<Scene> {
    load_gltf_bytes_with(bytes, path, &LoadOptions::default())
}

/// [`load_gltf_bytes`] with options.
pub fn load_gltf_bytes_with(bytes: &[u8], path: &Path, options: &LoadOptions) -> Result<Scene> {
    let assets = AssetReader::new(path, options).map_err(|e| Error::load(path, e))?;
    assets.given_main(bytes.len() as u64);
    load_with_reader(bytes, path, &assets, options)
}

fn load_with_reader(bytes: &[u8], path: &Path, assets: &AssetReader, options: &LoadOptions) -> Result<Scene> {
    let fail = |why: String| Error::load(path, why);
    let is_glb_name = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("glb"));
    let (json_bytes, bin) = if bytes.starts_with(b"glTF") {
        split_glb(bytes).map_err(fail)?
    } else if is_glb_name && b"glTF".starts_with(bytes) {
        return Err(fail(format!("truncated: {} bytes is too short for a GLB header", bytes.len())));
    } else if is_glb_name {
        let head = bytes.get(..4).unwrap_or(bytes);
        return Err(fail(format!(
            "wrong magic: a .glb file must start with \"glTF\", this one starts with {:?}",
            String::from_utf8_lossy(head)
        )));
    } else {
        (bytes, None)
    };
    let root = json::Root::from_slice(json_bytes).map_err(|e| fail(format!("invalid glTF JSON: {e}")))?;
    if !root.asset.version.starts_with("2.") {
        return Err(fail(format!("unsupported glTF version '{}' (expected 2.x)", root.asset.version)));
    }
    let mut warnings = Vec::new();
    for ext in &root.extensions_required {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            return Err(fail(format!("the file requires extension '{ext}', which this loader does not support")));
        }
    }
    for ext in &root.extensions_used {
        if !SUPPORTED_EXTENSIONS.contains(&ext.as_str()) {
            warnings.push(format!("ignoring unsupported glTF extension '{ext}'"));
        }
    }
    // The bytes wanted of each external file, by URI: the largest byteLength of the buffers
    // that name it and have views, so a file named by many buffers is read once.
    let mut uri_want: HashMap<&str, u64> = HashMap::new();
    let mut viewed = vec![false; root.buffers.len()];
    for v in &root.buffer_views {
        if let Some(f) = viewed.get_mut(v.buffer.value()) {
            *f = true;
        }
    }
    for (b, _) in root.buffers.iter().zip(&viewed).filter(|(_, &v)| v) {
        if let Some(uri) = &b.uri {
            let w = uri_want.entry(uri.as_str()).or_insert(0);
            *w = (*w).max(b.byte_length.0);
        }
    }
    let mut loader = Loader {
        root: &root,
        bin,
        bin_owner: root.buffers.iter().position(|b| b.uri.is_none()),
        buffers: root.buffers.iter().map(|_| OnceCell::new()).collect(),
        assets,
        uri_want,
        scene: Scene::new(),
        drawables: vec![None; root.meshes.len()],
        materials: vec![None; root.materials.len()],
        images: vec![None; root.images.len()],
        default_material: None,
        skipped: Vec::new(),
        node_ids: vec![Vec::new(); root.nodes.len()],
        unbacked: Cell::new(0),
        over_budget: Cell::new(false),
        max_nodes: options.max_nodes.unwrap_or(crate::assets::DEFAULT_MAX_NODES),
    };
    loader.scene.warnings = warnings;
    loader.build().map_err(fail)?;
    loader.load_animations().map_err(fail)?;
    let mut scene = loader.scene;
    let skipped = loader.skipped;
    if !skipped.is_empty() {
        let mut list = skipped.iter().take(5).cloned().collect::<Vec<_>>().join(", ");
        if skipped.len() > 5 {
            list.push_str(", ...");
        }
        scene
            .warnings
            .push(format!("skipped {} point/line primitive(s), only triangles are drawn: {list}", skipped.len()));
    }
    for w in &mut scene.warnings {
        *w = format!("{}: {w}", path.display());
    }
    Ok(scene)
}

// ---- container and buffers ----------------------------------------------------------------

/// A primitive drawn as triangles: its index in its glTF mesh, the mesh made of it, and its
/// material.
type Drawable = (usize, MeshId, Option<MaterialId>);

struct Loader<'a> {
    root: &'a json::Root,
    /// The GLB BIN chunk, and the buffer it belongs to (the first one without a URI).
    bin: Option<&'a [u8]>,
    bin_owner: Option<usize>,
    /// Buffers, loaded on first use.
    buffers: Vec<OnceCell<std::result::Result<BufferData<'a>, AssetError>>>,
    assets: &'a AssetReader,
    /// Bytes to read of each external buffer file, by URI.
    uri_want: HashMap<&'a str, u64>,
    scene: Scene,
    /// Per glTF mesh, once converted: its primitives drawn as triangles (index, mesh,
    /// material), shared by every node (and copy of a node) that draws the mesh.
    drawables: Vec<Option<Rc<[Drawable]>>>,
    materials: Vec<Option<MaterialId>>,
    /// Images, decoded (or failed) on first use.
    images: Vec<Option<std::result::Result<Arc<Texture>, AssetError>>>,
    default_material: Option<MaterialId>,
    skipped: Vec<String>,
    /// The scene nodes made for each glTF node: none when it is not in the loaded scene, one
    /// per path to it when it is shared by several parents.
    node_ids: Vec<Vec<NodeId>>,
    /// Accessor elements filled with zeros so far (accessors without a buffer view).
    unbacked: Cell<u64>,
    /// A charge against [`LoadOptions::max_decoded_bytes`] was refused: the load fails, also
    /// where the refusal would otherwise end as a warning (an animation channel skipped).
    over_budget: Cell<bool>,
    /// The most scene nodes this load may create.
    max_nodes: usize,
}

fn node_label(root: &json::Root, i: usize) -> String {
    label("node", i, root.nodes.get(i).and_then(|n| n.name.as_deref()))
}

/// How messages name object `i` of a kind ("mesh 3 ('wheel')"), its name [`cut`].
fn label(kind: &str, i: usize, name: Option<&str>) -> String {
    match name {
        Some(name) => format!("{kind} {i} ('{}')", cut(name)),
        None => format!("{kind} {i}"),
    }
}

/// A name as messages and labels quote it: one of a hostile length is cut at
/// [`LABEL_CHARS`] (a label names its object by index anyway), so that a label made once
/// per primitive or per copy of a node does not repeat a megabyte.
fn cut(name: &str) -> std::borrow::Cow<'_, str> {
    match name.char_indices().nth(LABEL_CHARS) {
        Some((at, _)) => format!("{}…", &name[..at]).into(),
        None => name.into(),
    }
}

/// The most characters of a node's name a message quotes.
const LABEL_CHARS: usize = 80;

/// A glTF node waiting in the depth-first walk of [`Loader::build`].
struct Visit {
    node: usize,
    depth: usize,
    /// The scene node it goes under.
    parent: Option<NodeId>,
    /// Whether the parent passes a material down.
    inherits: bool,
    /// The glTF node that lists it (`None`: the scene), named only in an error: a label per
    /// entry would copy a long name once per child entry.
    lister: Option<usize>,
}

/// The scene or the glTF node that lists a node, as error messages name it.
struct Referrer<'a>(&'a json::Root, Option<usize>);

impl std::fmt::Display for Referrer<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.1 {
            Some(i) => f.write_str(&node_label(self.0, i)),
            None => f.write_str("the scene"),
        }
    }
}

impl Loader<'_> {
    fn build(&mut self) -> std::result::Result<(), String> {
        let root = self.root;
        let roots: Vec<usize> = match root.scene.map(|s| s.value()) {
            Some(s) => {
                let sc = root.scenes.get(s).ok_or_else(|| format!("the default scene {s} does not exist"))?;
                sc.nodes.iter().map(|n| n.value()).collect()
            }
            None => match root.scenes.first() {
                Some(sc) => sc.nodes.iter().map(|n| n.value()).collect(),
                None => {
                    let mut is_child = vec![false; root.nodes.len()];
                    for n in &root.nodes {
                        for c in n.children.iter().flatten() {
                            if let Some(f) = is_child.get_mut(c.value()) {
                                *f = true;
                            }
                        }
                    }
                    (0..root.nodes.len()).filter(|&i| !is_child[i]).collect()
                }
            },
        };
        // A depth-first walk of the node graph as a DAG: a node reached again along another
        // path is loaded again; one reached again below itself is a cycle. `path` holds the
        // glTF nodes from the scene root to the current one (`on_path` flags them).
        let mut on_path = vec![false; root.nodes.len()];
        let mut path: Vec<usize> = Vec::new();
        let mut stack: Vec<Visit> = roots
            .iter()
            .rev()
            .map(|&node| Visit { node, depth: 0, parent: None, inherits: false, lister: None })
            .collect();
        while let Some(Visit { node: i, depth, parent, inherits, lister }) = stack.pop() {
            let referrer = Referrer(root, lister);
            let node = root.nodes.get(i).ok_or_else(|| format!("{referrer} lists node {i}, which does not exist"))?;
            while path.len() > depth {
                if let Some(left) = path.pop() {
                    on_path[left] = false;
                }
            }
            if on_path[i] {
                return Err(format!(
                    "{} is its own ancestor (reached again from {referrer}): the node graph has a cycle",
                    node_label(root, i)
                ));
            }
            if self.scene.node_count() >= self.max_nodes {
                return Err(format!(
                    "more than {} nodes once shared nodes are expanded (reached {} from {referrer}); \
                     the limit is LoadOptions::max_nodes",
                    self.max_nodes,
                    node_label(root, i)
                ));
            }
            on_path[i] = true;
            path.push(i);
            let label = node_label(root, i);
            // Each copy of a shared node stores its name again.
            let name = node.name.clone().unwrap_or_else(|| format!("node {i}"));
            self.charge(name.len() as u64, format_args!("the name of {label}"))?;
            // A TRS node keeps its TRS (animation lays samples over it); a matrix node its matrix.
            let mut desc = NodeDesc::new(name.clone());
            desc = match node.matrix {
                Some(m) => {
                    desc.matrix(crate::affine_from_mat4(&Mat4::from_cols_array(&m), &label).map_err(|e| e.to_string())?)
                }
                None => {
                    let t = node.translation.unwrap_or([0.0; 3]);
                    let r = node.rotation.map_or([0.0, 0.0, 0.0, 1.0], |q| q.0);
                    let s = node.scale.unwrap_or([1.0; 3]);
                    let trs =
                        Transform { translation: Vec3::from(t), rotation: Quat::from_array(r), scale: Vec3::from(s) };
                    desc.transform(trs.normalized(&label).map_err(|e| e.to_string())?)
                }
            };

            // The primitives this node draws.
            let prims = match node.mesh.map(|m| m.value()) {
                Some(m) if m >= root.meshes.len() => {
                    return Err(format!("{label} refers to mesh {m}, which does not exist"))
                }
                Some(m) => self.drawables(m)?,
                None => Rc::from([]),
            };
            if let [(_, mesh_id, mat)] = prims[..] {
                desc.mesh = Some(mesh_id);
                desc.material = self.resolve_material(mat, inherits);
            }
            let id = self.scene.add_node(parent, desc).map_err(|e| e.to_string())?;
            self.node_ids[i].push(id);
            let passes = inherits || self.scene.node(id).is_some_and(|n| n.material().is_some());
            if prims.len() > 1 {
                for &(p, mesh_id, mat) in prims.iter() {
                    let part = format!("{name} primitive {p}");
                    self.charge(part.len() as u64, format_args!("the name of {label}'s primitive {p}"))?;
                    let mut d = NodeDesc::new(part).mesh(mesh_id);
                    d.material = self.resolve_material(mat, inherits);
                    self.scene.add_node(Some(id), d).map_err(|e| e.to_string())?;
                }
            }
            if let Some(c) = node.camera {
                // Only the node's first copy reports an unusable camera.
                let first = self.node_ids[i].len() == 1;
                self.camera(c.value(), id, &label, first)?;
            }
            // Every entry waiting becomes a node at least: refuse before stacking more of them
            // than the limit allows (a file can list one child millions of times).
            let children = node.children.as_ref().map_or(0, Vec::len);
            if self.scene.node_count().saturating_add(stack.len()).saturating_add(children) > self.max_nodes {
                return Err(format!(
                    "more than {} nodes once shared nodes are expanded ({label} adds {children} children); \
                     the limit is LoadOptions::max_nodes",
                    self.max_nodes
                ));
            }
            for c in node.children.iter().flatten().rev() {
                stack.push(Visit {
                    node: c.value(),
                    depth: depth + 1,
                    parent: Some(id),
                    inherits: passes,
                    lister: Some(i),
                });
            }
        }
        Ok(())
    }

    /// Charges `n` bytes decoded or copied for `what` ([`LoadOptions::max_decoded_bytes`]).
    pub(super) fn charge(&self, n: u64, what: impl std::fmt::Display) -> std::result::Result<(), String> {
        self.assets.charge_decoded(n, what).inspect_err(|_| self.over_budget.set(true))
    }

    /// The material a primitive's node gets: its own, or — when an ancestor would otherwise
    /// pass one down (glTF has no material inheritance) — the default material.
    fn resolve_material(&mut self, own: Option<MaterialId>, inherits: bool) -> Option<MaterialId> {
        own.or_else(|| {
            inherits.then(|| *self.default_material.get_or_insert_with(|| self.scene.add_material(Material::default())))
        })
    }

    /// The primitives of mesh `m` drawn as triangles, converted on the first call: a node
    /// reached along many paths asks once per copy, and pays for what it draws, not for the
    /// mesh's other primitives.
    fn drawables(&mut self, m: usize) -> std::result::Result<Rc<[Drawable]>, String> {
        if let Some(Some(list)) = self.drawables.get(m) {
            return Ok(list.clone());
        }
        let mut list = Vec::new();
        for p in 0..self.root.meshes[m].primitives.len() {
            if let Some((mesh_id, mat)) = self.primitive(m, p)? {
                list.push((p, mesh_id, mat));
            }
        }
        let list: Rc<[Drawable]> = list.into();
        self.drawables[m] = Some(list.clone());
        Ok(list)
    }

    /// Converts primitive `p` of mesh `m` (called once per primitive); `None` when it is not
    /// drawn as triangles.
    #[allow(clippy::type_complexity)]
    fn primitive(&mut self, m: usize, p: usize) -> std::result::Result<Option<(MeshId, Option<MaterialId>)>, String> {
        let mesh = &self.root.meshes[m];
        let prim = &mesh.primitives[p];
        let label = format!("{} primitive {p}", label("mesh", m, mesh.name.as_deref()));
        let material = match prim.material {
            Some(mi) => Some(self.material(mi.value()).map_err(|e| format!("{label}: {e}"))?),
            None => None,
        };
        let converted = self.convert_primitive(m, p).map_err(|e| format!("{label}: {e}"))?;
        Ok(match converted {
            Some(mesh) => Some((self.scene.add_mesh(mesh), material)),
            None => {
                let mode = match prim.mode {
                    Checked::Valid(md) => format!("{md:?}"),
                    Checked::Invalid => "invalid".into(),
                };
                self.skipped.push(format!("{label} ({mode})"));
                None
            }
        })
    }

    fn convert_primitive(&self, m: usize, p: usize) -> std::result::Result<Option<Mesh>, String> {
        let mesh = &self.root.meshes[m];
        let prim = &mesh.primitives[p];
        let mode = match prim.mode {
            Checked::Valid(Mode::Triangles) => Mode::Triangles,
            Checked::Valid(Mode::TriangleStrip) => Mode::TriangleStrip,
            Checked::Valid(Mode::TriangleFan) => Mode::TriangleFan,
            Checked::Valid(_) => return Ok(None),
            Checked::Invalid => return Err("unknown primitive mode".into()),
        };
        let attr = |s: Semantic| prim.attributes.get(&Checked::Valid(s)).map(|a| a.value());
        let pos = attr(Semantic::Positions).ok_or("no POSITION attribute")?;
        let positions = self.read_vec3(pos, "POSITION")?;
        let n = positions.len();
        let normals = match attr(Semantic::Normals) {
            Some(a) => Some(self.read_vec3(a, "NORMAL")?),
            None => None,
        };
        let uvs = match attr(Semantic::TexCoords(0)) {
            Some(a) => Some(self.read_vec2(a, "TEXCOORD_0")?),
            None => None,
        };
        let seq = match prim.indices {
            Some(a) => self.read_indices(a.value())?,
            None => {
                let n = u32::try_from(n).map_err(|_| format!("{n} vertices is too many"))?;
                self.charge(n as u64 * 4, format_args!("listing the {n} vertices as indices"))?;
                (0..n).collect()
            }
        };
        if mode != Mode::Triangles {
            // A strip or fan of n indices becomes a list of 3(n − 2).
            let list = (seq.len() as u64).saturating_sub(2) * 3;
            self.charge(list * 4, format_args!("listing the triangles of a {mode:?} ({list} indices)"))?;
        }
        let indices = match mode {
            Mode::TriangleStrip => seq
                .windows(3)
                .enumerate()
                .flat_map(|(i, w)| if i % 2 == 0 { [w[0], w[1], w[2]] } else { [w[0], w[2], w[1]] })
                .collect(),
            Mode::TriangleFan => match seq.split_first() {
                Some((&first, rest)) => rest.windows(2).flat_map(|w| [first, w[0], w[1]]).collect(),
                None => Vec::new(),
            },
            _ => seq,
        };
        // The mesh's name is stored once per primitive.
        let name = match (&mesh.name, mesh.primitives.len()) {
            (Some(nm), 1) => nm.clone(),
            (Some(nm), _) => {
                self.charge(nm.len() as u64, "the mesh's name, stored with each of its primitives")?;
                format!("{nm} primitive {p}")
            }
            (None, 1) => format!("mesh {m}"),
            (None, _) => format!("mesh {m} primitive {p}"),
        };
        Mesh::new(name, positions, normals, uvs, indices).map(Some).map_err(|e| e.to_string())
    }

    /// Places camera `c` on `node` (one camera per copy of a glTF node, each storing the
    /// camera's name: charged); an unusable camera is ignored, with a warning when `warn`
    /// (the glTF node's first copy).
    fn camera(&mut self, c: usize, node: NodeId, node_label: &str, warn: bool) -> std::result::Result<(), String> {
        let Some(cam) = self.root.cameras.get(c) else {
            if warn {
                self.scene.warnings.push(format!("{node_label} refers to camera {c}, which does not exist; ignored"));
            }
            return Ok(());
        };
        let projection = match (&cam.type_, &cam.perspective, &cam.orthographic) {
            (Checked::Valid(json::camera::Type::Perspective), Some(p), _) => {
                let far = p.zfar.unwrap_or(DEFAULT_FAR.max(p.znear * 1.0e4));
                let aspect = p.aspect_ratio.unwrap_or(DEFAULT_ASPECT);
                Projection::perspective(crate::Angle::radians(p.yfov), aspect, p.znear, far).map_err(|e| e.to_string())
            }
            (Checked::Valid(json::camera::Type::Orthographic), _, Some(o)) => {
                Projection::orthographic(-o.xmag.abs(), o.xmag.abs(), -o.ymag.abs(), o.ymag.abs(), o.znear, o.zfar)
                    .map_err(|e| e.to_string())
            }
            _ => Err("its type and parameters do not match".to_string()),
        };
        match projection {
            Ok(projection) => {
                let name = match &cam.name {
                    Some(n) => {
                        self.charge(n.len() as u64, format_args!("the name of camera {c} on {node_label}"))?;
                        n.clone()
                    }
                    None => format!("camera {c}"),
                };
                self.scene.cameras.push(SceneCamera { name, node, projection });
            }
            Err(e) if warn => {
                let camera = label("camera", c, cam.name.as_deref());
                self.scene.warnings.push(format!("{camera} on {node_label}: {e}; ignored"));
            }
            Err(_) => {}
        }
        Ok(())
    }
}
