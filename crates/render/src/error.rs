//! The render crate's error type.

/// What can go wrong when setting up or running a render.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// A framebuffer size outside 1×1 ..= 8192×8192.
    #[error("invalid framebuffer size {width}x{height}: each side must be between 1 and 8192")]
    InvalidSize {
        /// Requested width.
        width: u32,
        /// Requested height.
        height: u32,
    },
    /// An error from the scene (stale handle, bad camera, ...).
    #[error(transparent)]
    Scene(#[from] sightline_scene::Error),
    /// A draw list entry that does not fit the instances or meshes given.
    #[error("invalid draw item: {0}")]
    InvalidDraw(String),
    /// A perspective near plane too close for the depth format to resolve the view.
    #[error(
        "near = {near} and far = {far} give a far/near ratio of {ratio:.3e}, beyond the {max_ratio:.3e} that \
         {format:?} depth can resolve (the far half of the view would round to the far plane): raise near or lower far"
    )]
    DepthRange {
        /// The near plane distance.
        near: f32,
        /// The far plane distance.
        far: f32,
        /// `(far − near) / near`.
        ratio: f64,
        /// The largest ratio the format resolves.
        max_ratio: f64,
        /// The depth format.
        format: crate::DepthFormat,
    },
    /// The scene was edited but its transforms were not propagated: drawing it would show
    /// a stale frame.
    #[error(
        "the scene has edits whose world transforms are not propagated yet: call Scene::update_transforms before rendering"
    )]
    NotPropagated,
    /// The scene draws more triangles than 32-bit triangle IDs can name.
    #[error(
        "the scene draws {triangles} triangles, more than the {max} that 32-bit triangle IDs can name: draw fewer instances or smaller meshes"
    )]
    TooManyTriangles {
        /// Triangles drawn by the scene's instances.
        triangles: u64,
        /// The most a scene may draw ([`sightline_scene::MAX_DRAWN_TRIANGLES`]).
        max: u64,
    },
    /// A culler or ray caster handed a scene other than the one it was built for.
    #[error(
        "this {structure} was built for another scene (a clone is another scene): build one for this scene, or draw through a World, which does"
    )]
    WrongScene {
        /// Which structure: "culler" or "ray caster".
        structure: &'static str,
    },
    /// A ray caster handed its scene after edits it has not followed yet.
    #[error("the scene changed since the ray caster was built or synced: call RayCaster::sync first")]
    NotSynced,
    /// A visibility method whose cost grows faster than the triangle count, handed more
    /// triangles than it is allowed to take.
    #[error(
        "{method} takes at most {limit} triangles and this scene has {triangles}: use a smaller scene (e.g. city:{limit}) or another method"
    )]
    TooLarge {
        /// The method's name.
        method: &'static str,
        /// Triangles in the scene.
        triangles: usize,
        /// The most the method takes.
        limit: usize,
    },
    /// A visibility method that needed more of some bounded resource (splits, windows, …)
    /// than its limit allows: the input is degenerate or far harder than the method is
    /// meant for.
    #[error("{method} gave up: the scene needs more than {limit} {what}; use another method for this scene")]
    LimitExceeded {
        /// The method's name.
        method: &'static str,
        /// What ran out.
        what: &'static str,
        /// The bound.
        limit: u64,
    },
    /// Render options that cannot be honoured.
    #[error("invalid render options: {0}")]
    InvalidOptions(String),
    /// A method that keeps fragments per pixel handed a frame with more of them than it
    /// keeps.
    #[error(
        "{method} keeps at most {limit} fragments and this frame has more: draw fewer or smaller transparent surfaces, a smaller image, or use depth peeling"
    )]
    TooManyFragments {
        /// The method's name.
        method: &'static str,
        /// The most fragments the method keeps.
        limit: u64,
    },
    /// Writing an output file failed.
    #[error("{path}: {why}")]
    Output {
        /// The file.
        path: String,
        /// What went wrong.
        why: String,
    },
}

/// Result alias for the render crate.
pub type Result<T, E = Error> = std::result::Result<T, E>;

/// Whether the `structure` ("culler", "ray caster") built for the scene `built_for` may
/// follow `scene`: it must be that scene, propagated, and drawable ([`check_drawable`]).
pub(crate) fn check_followable(
    scene: &sightline_scene::Scene,
    built_for: sightline_scene::SceneId,
    structure: &'static str,
) -> Result<()> {
    if scene.id() != built_for {
        return Err(Error::WrongScene { structure });
    }
    if scene.needs_update() {
        return Err(Error::NotPropagated);
    }
    check_drawable(scene)
}

/// Whether `scene` (propagated) can be drawn: [`Error::TooManyTriangles`] when it draws more
/// triangles than IDs can name (its instances' first IDs would stop at `u32::MAX` and
/// repeat), the scene's error when a world transform overflowed.
pub(crate) fn check_drawable(scene: &sightline_scene::Scene) -> Result<()> {
    scene.check_world_transforms()?;
    let (triangles, max) = (scene.drawn_triangle_count(), sightline_scene::MAX_DRAWN_TRIANGLES);
    if triangles > max {
        return Err(Error::TooManyTriangles { triangles, max });
    }
    Ok(())
}
