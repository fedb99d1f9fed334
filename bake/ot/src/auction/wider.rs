//! The auction's rows widened beyond its graph: each row's newest list of candidates, and the
//! room those lists may take (D174).

use super::{Widened, NONE};

/// The rows whose candidates were widened beyond the graph.
///
/// A row widened again replaces its list; the one it replaced stays in `cols`, unread, until the
/// lists would pass the limit, and is then compacted away. The limit counts only the lists rows
/// still read: counting every list ever made parked the 16M cow's later rows for the augmenting
/// paths (a minute each) with most of the limit held by lists no row read any more (D174).
#[derive(Default)]
pub(super) struct Wider {
    /// Row → index into `rows` (`NONE`: the graph's own), allocated at the first widening.
    index: Vec<u32>,
    rows: Vec<WideRow>,
    /// Every list, one after the other, including replaced ones not yet compacted away.
    cols: Vec<u32>,
    /// Columns of the lists rows still read, and the most they held at once.
    live: usize,
    pub held: usize,
    /// Lists kept, and their columns, over the whole auction (the report's count).
    pub lists: u64,
    pub listed: usize,
    /// Rows parked because their list would pass the limit.
    pub refused: u64,
}

struct WideRow {
    /// The row's list in `cols`, or `None`: the graph's own candidates.
    list: Option<(usize, usize)>,
    certified: f64,
    round: u32,
}

/// Compaction must win back at least this fraction of the limit, or the list is refused: near a
/// limit held by live lists, compacting for every widening would copy them all each time.
const COMPACT_GAIN: usize = 16;

impl Wider {
    /// Row i's list (`None`: the graph's own) and what it certifies, with its round, if it was
    /// widened.
    pub fn get(&self, i: usize) -> Option<(Option<&[u32]>, f64, u32)> {
        match self.index.get(i) {
            Some(&k) if k != NONE => {
                let w = &self.rows[k as usize];
                let list = w.list.map(|(a, len)| &self.cols[a..a + len]);
                Some((list, w.certified, w.round))
            }
            _ => None,
        }
    }

    /// Records what widening row i found; `false` (nothing recorded) if its list would pass
    /// `limit` with the other rows' lists.
    pub fn set(&mut self, rows: usize, i: usize, found: Widened, round: u32, limit: usize) -> bool {
        let old = self
            .get(i)
            .and_then(|(list, ..)| list)
            .map_or(0, <[u32]>::len);
        let (list, certified) = match found {
            Widened::Own(certified) => (None, certified),
            Widened::List(cols, certified) => {
                let len = cols.len();
                if self.live - old + len > limit {
                    self.refused += 1;
                    return false;
                }
                if self.cols.len() + len > limit {
                    // What compaction wins back: every replaced list, and this row's own.
                    if self.cols.len() - self.live + old < limit / COMPACT_GAIN {
                        self.refused += 1;
                        return false;
                    }
                    self.compact(i);
                }
                let start = self.cols.len();
                self.cols.extend_from_slice(&cols);
                self.lists += 1;
                self.listed += len;
                (Some((start, len)), certified)
            }
        };
        self.live = self.live - old + list.map_or(0, |(_, len)| len);
        self.held = self.held.max(self.live);
        if self.index.is_empty() {
            self.index = vec![NONE; rows];
        }
        let row = WideRow {
            list,
            certified,
            round,
        };
        match self.index[i] {
            NONE => {
                self.index[i] = self.rows.len() as u32;
                self.rows.push(row);
            }
            k => self.rows[k as usize] = row,
        }
        true
    }

    /// Moves the lists rows still read (all but row `except`'s, about to be replaced) to the front
    /// of `cols`, in their order there, and lets the replaced ones go.
    fn compact(&mut self, except: usize) {
        let skip = self.index.get(except).copied().unwrap_or(NONE);
        let mut order: Vec<(usize, u32)> = (self.rows.iter().enumerate())
            .filter(|&(k, _)| k as u32 != skip)
            .filter_map(|(k, w)| w.list.map(|(start, _)| (start, k as u32)))
            .collect();
        order.sort_unstable();
        let mut end = 0;
        for (start, k) in order {
            let w = &mut self.rows[k as usize];
            if let Some((_, len)) = w.list {
                self.cols.copy_within(start..start + len, end);
                w.list = Some((end, len));
                end += len;
            }
        }
        self.cols.truncate(end);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lists a row replaced do not count against the limit: rows widened again and again, each
    /// new list within the limit with the other rows' newest ones, are all kept, `cols` never
    /// passes the limit (compaction lets the replaced lists go), and every row still reads its
    /// newest list.
    #[test]
    fn replaced_lists_make_room_for_new_ones() {
        let (rows, limit) = (8, 64);
        let list = |i: usize, round: u32| -> Vec<u32> {
            let len = 1 + (i + round as usize) % 5;
            (0..len as u32)
                .map(|k| 1000 * i as u32 + 10 * round + k)
                .collect()
        };
        let mut w = Wider::default();
        let mut made = 0;
        for round in 0..12 {
            for i in 0..rows {
                made += list(i, round).len();
                let found = Widened::List(list(i, round), f64::from(round));
                assert!(
                    w.set(rows, i, found, round, limit),
                    "row {i}, round {round}"
                );
                assert!(w.cols.len() <= limit, "{} columns held", w.cols.len());
            }
            for i in 0..rows {
                let (cols, certified, r) = w.get(i).unwrap();
                assert_eq!(cols.unwrap(), &list(i, round)[..], "row {i}, round {round}");
                assert_eq!((certified, r), (f64::from(round), round));
            }
        }
        assert!(
            made > 4 * limit,
            "the lists made pass the limit many times over"
        );
        assert_eq!((w.refused, w.lists, w.listed), (0, 96, made));
    }

    /// A list that would pass the limit with the other rows' lists is refused (the row is left
    /// as it was); a list replaced by a new one, or by the row's own candidates, frees its room.
    #[test]
    fn a_list_past_the_limit_with_the_others_is_refused() {
        let (rows, limit) = (3, 5);
        let mut w = Wider::default();
        assert!(w.set(rows, 0, Widened::List(vec![1, 2, 3], 1.0), 0, limit));
        assert!(!w.set(rows, 1, Widened::List(vec![4, 5, 6], 1.0), 0, limit));
        assert_eq!(w.refused, 1);
        assert!(
            w.get(1).is_none(),
            "a refused row keeps the graph's own candidates"
        );
        // Row 0's new list replaces its old one: only the new one counts.
        assert!(w.set(rows, 0, Widened::List(vec![7, 8, 9, 10, 11], 2.0), 1, limit));
        assert_eq!(w.get(0).unwrap().0.unwrap(), &[7, 8, 9, 10, 11]);
        // Its own candidates again: the list's room is free for row 1.
        assert!(w.set(rows, 0, Widened::Own(3.0), 2, limit));
        assert!(w.set(rows, 1, Widened::List(vec![4, 5, 6], 1.0), 0, limit));
        assert_eq!(w.get(0).unwrap(), (None, 3.0, 2));
        assert_eq!(w.get(1).unwrap().0.unwrap(), &[4, 5, 6]);
        assert_eq!(w.cols, [4, 5, 6], "the replaced lists were let go");
        assert_eq!(w.live, 3);
    }
}
