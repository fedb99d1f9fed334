//! A fixed-capacity traversal stack: depth-first traversal without recursion or allocation.
//!
//! Depth-first traversal pops one node and pushes at most its two children, so the stack never holds
//! more than one pending sibling per level plus the current pair: at most `depth + 2` entries.
//! Archives are validated to `depth <= 28`, so [`CAPACITY`] = 64 can never overflow; `push` still
//! refuses (returns `false`) rather than panicking if that reasoning were ever broken.

use otbake_formats::tree::Node;

/// Entries the stack can hold.
pub const CAPACITY: usize = 64;

/// The stack.
pub struct Stack {
    items: [Node; CAPACITY],
    len: usize,
}

impl Stack {
    /// A stack holding `root`.
    pub fn new(root: Node) -> Self {
        let mut s = Self {
            items: [root; CAPACITY],
            len: 0,
        };
        s.push(root);
        s
    }

    /// Pushes `node`; `false` if full.
    pub fn push(&mut self, node: Node) -> bool {
        match self.items.get_mut(self.len) {
            Some(slot) => {
                *slot = node;
                self.len += 1;
                true
            }
            None => false,
        }
    }

    /// Pops the top node.
    pub fn pop(&mut self) -> Option<Node> {
        self.len = self.len.checked_sub(1)?;
        self.items.get(self.len).copied()
    }
}
