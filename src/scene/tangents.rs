//! Tangents for normal maps where a file gives none: MikkTSpace, as Blender and the glTF
//! sample viewer compute them, so that normal maps baked against it shade as their author saw.

/// A triangle list seen through the MikkTSpace interface.
struct Triangles<'a> {
    positions: &'a [[f32; 3]],
    normals: &'a [[f32; 3]],
    coords: &'a [[f32; 2]],
    indices: &'a [u32],
    tangents: Vec<[f32; 4]>,
}

impl Triangles<'_> {
    fn vertex(&self, face: usize, corner: usize) -> usize {
        self.indices[face * 3 + corner] as usize
    }
}

impl bevy_mikktspace::Geometry for Triangles<'_> {
    fn num_faces(&self) -> usize {
        self.indices.len() / 3
    }

    fn num_vertices_of_face(&self, _face: usize) -> usize {
        3
    }

    fn position(&self, face: usize, vert: usize) -> [f32; 3] {
        self.positions[self.vertex(face, vert)]
    }

    fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
        self.normals[self.vertex(face, vert)]
    }

    fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
        self.coords[self.vertex(face, vert)]
    }

    fn set_tangent_encoded(&mut self, tangent: [f32; 4], face: usize, vert: usize) {
        let v = self.vertex(face, vert);
        self.tangents[v] = tangent;
    }
}

/// Per-vertex tangents (xyz unit, w the bitangent's sign) for a triangle list with the normal
/// map's texture coordinates; `None` where MikkTSpace cannot build them.
pub fn generate_tangents(
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    coords: &[[f32; 2]],
    indices: &[u32],
) -> Option<Vec<[f32; 4]>> {
    let mut triangles = Triangles {
        positions,
        normals,
        coords,
        indices,
        tangents: vec![[0.0; 4]; positions.len()],
    };
    if !bevy_mikktspace::generate_tangents(&mut triangles) {
        return None;
    }
    let tangents = triangles.tangents;
    tangents
        .iter()
        .all(|t| t.iter().all(|c| c.is_finite()))
        .then_some(tangents)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quad_mapped_along_x_has_tangents_along_x() {
        // A floor quad whose u grows with x and v with −z (image rows go down): tangent +x,
        // bitangent (n × t · w) along the direction of growing v.
        let positions = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, -1.0],
            [0.0, 0.0, -1.0],
        ];
        let normals = [[0.0, 1.0, 0.0]; 4];
        let coords = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
        let indices = [0, 1, 2, 0, 2, 3];
        let t = generate_tangents(&positions, &normals, &coords, &indices).unwrap();
        for tangent in t {
            assert!((tangent[0] - 1.0).abs() < 1e-5, "{tangent:?}");
            assert!(tangent[1].abs() < 1e-5 && tangent[2].abs() < 1e-5);
            // n × t = y × x = −z, and v grows towards +z here: w = −1.
            assert_eq!(tangent[3], -1.0);
        }
    }
}
