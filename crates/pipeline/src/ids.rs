//! Typed ids of the pipeline's data, and a vector indexed by them.
//!
//! Every list of the pipeline is indexed by what it lists: images and cameras in the
//! project's order, the scene's points, the detections of one image, the LRF spheres. A
//! bare `usize` would let an image index open a camera list; each id here is its own type,
//! and [`IdVec<I, T>`] is a `Vec<T>` that only an `I` opens. A detection is named by its
//! image and its index in that image ([`DetectionId`]).
//!
//! The ids are positions: a [`PointId`] names a point of the scene as the scene stands, and
//! removing a point moves the ones after it (the pipeline never keeps a point id across a
//! removal).

use std::marker::PhantomData;
use std::ops::{Index, IndexMut};

/// An index into an [`IdVec`].
pub trait Id: Copy + Eq + Ord + std::fmt::Debug {
    /// The id of position `i`.
    fn new(i: usize) -> Self;
    /// The position it names.
    fn index(self) -> usize;
}

macro_rules! id {
    ($(#[$doc:meta])* $name:ident) => {
        $(#[$doc])*
        #[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub struct $name(pub usize);

        impl Id for $name {
            fn new(i: usize) -> Self {
                Self(i)
            }
            fn index(self) -> usize {
                self.0
            }
        }
    };
}

id!(
    /// An image of the project (position in `[[images]]`).
    ImageId
);
id!(
    /// A camera of the project (position in `[[cameras]]`).
    CameraId
);
id!(
    /// A point of the scene (coded target, plain target or ball).
    PointId
);
id!(
    /// A detection within one image (position in its target list).
    DetIdx
);
id!(
    /// A sphere fitted in the LRF cloud (position in the finder's list).
    SphereId
);

/// One detection of the project: the image and its index there.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct DetectionId {
    /// The image.
    pub image: ImageId,
    /// The detection within it.
    pub det: DetIdx,
}

impl DetectionId {
    /// Detection `det` of `image`.
    pub fn new(image: ImageId, det: DetIdx) -> Self {
        Self { image, det }
    }
}

/// A `Vec<T>` indexed by `I` only.
#[derive(Clone, Debug, PartialEq)]
pub struct IdVec<I, T> {
    items: Vec<T>,
    id: PhantomData<fn(I) -> I>,
}

impl<I: Id, T> IdVec<I, T> {
    /// An empty vector.
    pub fn new() -> Self {
        Vec::new().into()
    }

    /// Number of items.
    pub fn len(&self) -> usize {
        self.items.len()
    }

    /// Whether there is none.
    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Appends `item` and returns its id.
    pub fn push(&mut self, item: T) -> I {
        self.items.push(item);
        I::new(self.items.len() - 1)
    }

    /// Removes and returns the item of `id`; the items after it move down by one.
    pub fn remove(&mut self, id: I) -> T {
        self.items.remove(id.index())
    }

    /// Keeps the items for which `keep` is true.
    pub fn retain(&mut self, keep: impl FnMut(&T) -> bool) {
        self.items.retain(keep);
    }

    /// The ids, in order.
    pub fn ids(&self) -> impl DoubleEndedIterator<Item = I> + ExactSizeIterator {
        (0..self.items.len()).map(I::new)
    }

    /// The items, in order.
    pub fn iter(&self) -> std::slice::Iter<'_, T> {
        self.items.iter()
    }

    /// The items, in order, to change.
    pub fn iter_mut(&mut self) -> std::slice::IterMut<'_, T> {
        self.items.iter_mut()
    }

    /// (id, item) pairs, in order.
    pub fn iter_enumerated(&self) -> impl DoubleEndedIterator<Item = (I, &T)> {
        self.items.iter().enumerate().map(|(i, t)| (I::new(i), t))
    }

    /// The id of the first item for which `f` is true.
    pub fn position(&self, f: impl FnMut(&T) -> bool) -> Option<I> {
        self.items.iter().position(f).map(I::new)
    }

    /// The items as a plain slice (for APIs outside the pipeline).
    pub fn as_slice(&self) -> &[T] {
        &self.items
    }
}

impl<I: Id, T> Default for IdVec<I, T> {
    fn default() -> Self {
        Self::new()
    }
}

impl<I, T> From<Vec<T>> for IdVec<I, T> {
    fn from(items: Vec<T>) -> Self {
        Self {
            items,
            id: PhantomData,
        }
    }
}

impl<I, T> FromIterator<T> for IdVec<I, T> {
    fn from_iter<It: IntoIterator<Item = T>>(iter: It) -> Self {
        iter.into_iter().collect::<Vec<T>>().into()
    }
}

impl<I, T> IntoIterator for IdVec<I, T> {
    type Item = T;
    type IntoIter = std::vec::IntoIter<T>;
    fn into_iter(self) -> Self::IntoIter {
        self.items.into_iter()
    }
}

impl<'a, I, T> IntoIterator for &'a IdVec<I, T> {
    type Item = &'a T;
    type IntoIter = std::slice::Iter<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.items.iter()
    }
}

impl<'a, I, T> IntoIterator for &'a mut IdVec<I, T> {
    type Item = &'a mut T;
    type IntoIter = std::slice::IterMut<'a, T>;
    fn into_iter(self) -> Self::IntoIter {
        self.items.iter_mut()
    }
}

impl<I: Id, T> Index<I> for IdVec<I, T> {
    type Output = T;
    fn index(&self, id: I) -> &T {
        &self.items[id.index()]
    }
}

impl<I: Id, T> IndexMut<I> for IdVec<I, T> {
    fn index_mut(&mut self, id: I) -> &mut T {
        &mut self.items[id.index()]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ids_open_their_own_vector() {
        let mut v: IdVec<ImageId, &str> = IdVec::new();
        let a = v.push("a.png");
        let b = v.push("b.png");
        assert_eq!((a, b), (ImageId(0), ImageId(1)));
        assert_eq!(v[b], "b.png");
        v[a] = "c.png";
        assert_eq!(
            v.iter_enumerated().collect::<Vec<_>>(),
            vec![(ImageId(0), &"c.png"), (ImageId(1), &"b.png")]
        );
        assert_eq!(v.position(|s| *s == "b.png"), Some(b));
        assert_eq!(v.ids().collect::<Vec<_>>(), vec![a, b]);
        assert_eq!(v.remove(a), "c.png");
        assert_eq!(v[ImageId(0)], "b.png");
    }

    #[test]
    fn detections_order_by_image_then_index() {
        let d = |i, k| DetectionId::new(ImageId(i), DetIdx(k));
        let mut v = vec![d(1, 0), d(0, 5), d(0, 2)];
        v.sort();
        assert_eq!(v, vec![d(0, 2), d(0, 5), d(1, 0)]);
    }
}
