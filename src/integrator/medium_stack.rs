//! Which closed-mesh interior a ray is in: a ray is in the interior it most recently entered and has not yet
//! left, so interiors nest (a medium stack). Position-filled media (VDB volumes) are not on the stack.

/// Deepest nesting of interiors tracked; deeper entries are ignored.
const CAPACITY: usize = 8;

/// A small fixed-capacity stack of medium indices.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct MediumStack {
    entries: [u32; CAPACITY],
    len: usize,
}

impl MediumStack {
    /// The medium the ray is in now, if any.
    pub fn current(&self) -> Option<u32> {
        self.len.checked_sub(1).map(|i| self.entries[i])
    }

    /// Updates the stack for a ray crossing the boundary of an interior `medium`: entering when `entering`,
    /// leaving otherwise (the most recent entry of that medium is removed).
    pub fn cross(&mut self, medium: u32, entering: bool) {
        if entering {
            if self.len < CAPACITY {
                self.entries[self.len] = medium;
                self.len += 1;
            }
        } else if let Some(i) = self.entries[..self.len].iter().rposition(|&m| m == medium) {
            self.entries.copy_within(i + 1..self.len, i);
            self.len -= 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nested_interiors() {
        let mut s = MediumStack::default();
        assert_eq!(s.current(), None);
        s.cross(1, true);
        s.cross(2, true);
        assert_eq!(s.current(), Some(2));
        s.cross(1, false); // leaving the outer one first (overlapping meshes)
        assert_eq!(s.current(), Some(2));
        s.cross(2, false);
        assert_eq!(s.current(), None);
        s.cross(3, false); // leaving something never entered is ignored
        assert_eq!(s.current(), None);
    }
}
