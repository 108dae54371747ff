//! What one scene may cost (file size, mesh instances, vertices, triangles, texture size and
//! memory), checked before anything is allocated for it; `[budgets]` in the config sets it.

/// Limits on a scene (defaults: see [`SceneBudget::default`]; the book's budgets reference).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SceneBudget {
    /// Largest scene file, and each external buffer or image it names.
    pub max_file_bytes: u64,
    /// Mesh instances after expanding the node graph (a node listed twice as a child, or a
    /// mesh used by many nodes, counts each time it is drawn); nodes visited count too.
    pub max_instances: u64,
    /// Vertices after expanding instances.
    pub max_vertices: u64,
    /// Triangles after expanding instances.
    pub max_triangles: u64,
    /// Longest texture side; larger images are downscaled, with a warning.
    pub max_texture_side: u32,
    /// All textures together, with their mip levels (RGBA8, 4/3 of the base level).
    pub max_texture_bytes: u64,
    /// Joints of one skin.
    pub max_joints: u32,
    /// Morph targets of one primitive.
    pub max_morph_targets: u32,
    /// Animation channels of the file, every animation together.
    pub max_animation_channels: u32,
    /// Keyframes of the file, every channel together.
    pub max_keyframes: u32,
    /// What the posed primitives hold for posing (mesh-space vertices, morph deltas, skin
    /// weights), CPU and GPU copies together.
    pub max_pose_bytes: u64,
}

impl Default for SceneBudget {
    fn default() -> Self {
        // Sized for a lab's GPU (8 GB and more) with room for the tessellator and the walls:
        // 32 M vertices are 2.3 GB of vertex data (72 bytes each), and 1.5 GB of textures
        // hold four 8192² images with their mips or ninety-six 2048² ones.
        Self {
            max_file_bytes: 2 << 30,
            max_instances: 1 << 20,
            max_vertices: 32 << 20,
            max_triangles: 32 << 20,
            max_texture_side: 8192,
            max_texture_bytes: 1536 << 20,
            max_joints: super::rig::DEFAULT_MAX_JOINTS,
            max_morph_targets: super::rig::DEFAULT_MAX_MORPH_TARGETS,
            max_animation_channels: super::rig::DEFAULT_MAX_CHANNELS,
            max_keyframes: super::rig::DEFAULT_MAX_KEYFRAMES,
            max_pose_bytes: 1 << 30,
        }
    }
}

/// Running totals while the node graph is expanded, checked against a [`SceneBudget`].
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct SceneTotals {
    pub instances: u64,
    pub vertices: u64,
    pub triangles: u64,
}

impl SceneTotals {
    /// Adds one instance of `vertices` and `triangles`; the first budget passed, as
    /// "N things, over budgets.FIELD = M".
    pub fn add(
        &mut self,
        vertices: u64,
        triangles: u64,
        budget: &SceneBudget,
    ) -> Result<(), String> {
        self.instances = self.instances.saturating_add(1);
        self.vertices = self.vertices.saturating_add(vertices);
        self.triangles = self.triangles.saturating_add(triangles);
        let over = |what: &str, got: u64, field: &str, max: u64| {
            format!("the scene reaches {got} {what} here, over budgets.{field} = {max}")
        };
        if self.instances > budget.max_instances {
            return Err(over(
                "instances (nodes and meshes drawn)",
                self.instances,
                "max_instances",
                budget.max_instances,
            ));
        }
        if self.vertices > budget.max_vertices {
            return Err(over(
                "vertices",
                self.vertices,
                "max_vertices",
                budget.max_vertices,
            ));
        }
        if self.triangles > budget.max_triangles {
            return Err(over(
                "triangles",
                self.triangles,
                "max_triangles",
                budget.max_triangles,
            ));
        }
        Ok(())
    }
}

/// The size an image is drawn at under `max_side` (aspect kept, at least 1 pixel).
pub fn fitted_size(width: u32, height: u32, max_side: u32) -> (u32, u32) {
    let longest = width.max(height);
    if longest <= max_side {
        return (width, height);
    }
    let scale = f64::from(max_side) / f64::from(longest);
    let fit = |side: u32| ((f64::from(side) * scale).round() as u32).clamp(1, max_side);
    (fit(width), fit(height))
}

/// Bytes of an RGBA8 texture with its full mip chain.
pub fn texture_bytes(width: u32, height: u32) -> u64 {
    let base = u64::from(width) * u64::from(height) * 4;
    base + base / 3
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn totals_name_the_budget_they_pass() {
        let budget = SceneBudget {
            max_vertices: 10,
            ..SceneBudget::default()
        };
        let mut totals = SceneTotals::default();
        assert!(totals.add(6, 2, &budget).is_ok());
        let e = totals.add(6, 2, &budget).unwrap_err();
        assert!(
            e.contains("12 vertices") && e.contains("budgets.max_vertices = 10"),
            "{e}"
        );
        // Saturates instead of wrapping.
        let mut totals = SceneTotals::default();
        assert!(
            totals
                .add(u64::MAX, u64::MAX, &SceneBudget::default())
                .is_err()
        );
        assert!(totals.add(u64::MAX, 1, &SceneBudget::default()).is_err());
        assert_eq!(totals.vertices, u64::MAX);
    }

    #[test]
    fn large_images_fit_the_side_keeping_their_aspect() {
        assert_eq!(fitted_size(16384, 8192, 8192), (8192, 4096));
        assert_eq!(fitted_size(100, 50, 8192), (100, 50));
        assert_eq!(fitted_size(65535, 1, 1024), (1024, 1));
        assert_eq!(texture_bytes(4, 4), 64 + 21);
    }
}
