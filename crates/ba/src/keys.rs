//! Typed keys of a [`Problem`]'s blocks (as factrs' keys): a residual names the point, the
//! image pose or the parameter block it depends on by a key of that kind, so that a point's
//! index cannot be passed where a parameter block's is meant. A key is the block's index in
//! the problem's vector of that kind ([`Problem::points`], [`Problem::images`],
//! [`Problem::parameters`]); `problem[key]` is the block.

use crate::problem::{Image, Point, Problem};
use crate::residual::ParameterBlock;

/// An object point of a problem (index into [`Problem::points`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PointKey(pub usize);

/// An image of a problem, its pose (index into [`Problem::images`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ImageKey(pub usize);

/// One of a problem's own parameter blocks (index into [`Problem::parameters`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct ParameterKey(pub usize);

impl Problem {
    /// Appends a parameter block and returns its key.
    pub fn add_parameter(&mut self, block: ParameterBlock) -> ParameterKey {
        self.parameters.push(block);
        ParameterKey(self.parameters.len() - 1)
    }
}

impl std::ops::Index<PointKey> for Problem {
    type Output = Point;
    fn index(&self, k: PointKey) -> &Point {
        &self.points[k.0]
    }
}

impl std::ops::Index<ImageKey> for Problem {
    type Output = Image;
    fn index(&self, k: ImageKey) -> &Image {
        &self.images[k.0]
    }
}

impl std::ops::Index<ParameterKey> for Problem {
    type Output = ParameterBlock;
    fn index(&self, k: ParameterKey) -> &ParameterBlock {
        &self.parameters[k.0]
    }
}

impl std::ops::IndexMut<ParameterKey> for Problem {
    fn index_mut(&mut self, k: ParameterKey) -> &mut ParameterBlock {
        &mut self.parameters[k.0]
    }
}
