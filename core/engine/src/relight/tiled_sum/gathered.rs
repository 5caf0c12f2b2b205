//! A list filled within the capacity reserved for it, for the loops over a tile's entries
//! that gather some of them.

/// A list filled within the capacity reserved for it, so that adding to it calls nothing
/// (a call in the loop over a tile's entries would have the kernel's register accumulators
/// spilled around it).
pub(super) struct Gathered<'a, T> {
    list: &'a mut Vec<T>,
}

impl<'a, T> Gathered<'a, T> {
    /// `list`, emptied, with room for `most` items.
    pub(super) fn new(list: &'a mut Vec<T>, most: usize) -> Self {
        list.clear();
        list.reserve(most);
        Gathered { list }
    }

    /// Appends `item`.
    ///
    /// # Panics
    /// Past the room reserved.
    #[inline(always)]
    pub(super) fn push(&mut self, item: T) {
        let len = self.list.len();
        self.list.spare_capacity_mut()[0].write(item);
        // SAFETY: the item at `len` was just written.
        unsafe { self.list.set_len(len + 1) };
    }
}
