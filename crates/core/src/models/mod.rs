//! The tissue models and their shape information (the paper's name for the arrays a model
//! needs beyond positions, velocities, forces and neighbours, section 4 and Table 1).
//!
//! Only the chosen model's arrays are allocated.

pub mod local_shape_matching;
pub mod mass_spring;
pub mod mueller2016_rotation;

use crate::math::{Vec4, QUAT_IDENTITY};
use crate::neighbours::Neighbours;
use crate::scene::{Material, ShapeMatchingForces, ShapeMatchingParams};

/// Per-model shape information arrays, sized for the full capacity.
#[derive(Debug, Clone, PartialEq)]
pub enum ShapeInfo {
    /// Mass-spring: rest length per neighbour slot.
    MassSpring {
        /// `capacity * K` rest lengths in metres.
        rest_length: Vec<f32>,
    },
    /// Local shape matching: rest positions, shape vectors and warm-start rotations.
    LocalShapeMatching {
        /// Rest positions x0 (w = 0).
        rest_position: Vec<Vec4>,
        /// Shape vectors v = x0 - C0 (w = 0).
        shape_vector: Vec<Vec4>,
        /// Rotation quaternions `[x, y, z, w]` from the last step.
        rotation: Vec<Vec4>,
        /// Cluster centre offsets c_i of the current step (`cluster` variant only).
        cluster_centre: Option<Vec<Vec4>>,
    },
}

/// Name and size of one allocated array.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ArrayInfo {
    /// Array name.
    pub name: &'static str,
    /// Bytes allocated.
    pub bytes: usize,
}

impl ShapeInfo {
    /// Builds the chosen model's shape information for the first `n` of `rest` (rest
    /// positions of all `capacity` slots).
    pub fn build(material: &Material, rest: &[Vec4], nb: &Neighbours, n: usize) -> ShapeInfo {
        let capacity = rest.len();
        match material {
            Material::MassSpring(_) => ShapeInfo::MassSpring {
                rest_length: mass_spring::rest_lengths(rest, nb, n),
            },
            Material::LocalShapeMatching(ShapeMatchingParams { forces, .. }) => {
                let rest_position: Vec<Vec4> =
                    rest.iter().map(|p| [p[0], p[1], p[2], 0.0]).collect();
                let mut shape_vector = vec![[0.0f32; 4]; capacity];
                for (i, v) in shape_vector.iter_mut().enumerate().take(n) {
                    *v = local_shape_matching::shape_vector(i, &rest_position, nb);
                }
                ShapeInfo::LocalShapeMatching {
                    rest_position,
                    shape_vector,
                    rotation: vec![QUAT_IDENTITY; capacity],
                    cluster_centre: (*forces == ShapeMatchingForces::Cluster)
                        .then(|| vec![[0.0; 4]; capacity]),
                }
            }
        }
    }

    /// The arrays this model allocated, with their sizes.
    pub fn arrays(&self) -> Vec<ArrayInfo> {
        fn bytes<T>(v: &[T]) -> usize {
            std::mem::size_of_val(v)
        }
        match self {
            ShapeInfo::MassSpring { rest_length } => vec![ArrayInfo {
                name: "rest_length",
                bytes: bytes(rest_length),
            }],
            ShapeInfo::LocalShapeMatching {
                rest_position,
                shape_vector,
                rotation,
                cluster_centre,
            } => {
                let mut v = vec![
                    ArrayInfo {
                        name: "rest_position",
                        bytes: bytes(rest_position),
                    },
                    ArrayInfo {
                        name: "shape_vector",
                        bytes: bytes(shape_vector),
                    },
                    ArrayInfo {
                        name: "rotation",
                        bytes: bytes(rotation),
                    },
                ];
                if let Some(c) = cluster_centre {
                    v.push(ArrayInfo {
                        name: "cluster_centre",
                        bytes: bytes(c),
                    });
                }
                v
            }
        }
    }
}
