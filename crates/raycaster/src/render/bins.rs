//! [`Bins`]: items sorted into numbered bins in two passes (count, then
//! fill), so each bin's items are one slice, in item order, with nothing
//! allocated per bin and no list to overflow. The screen-space passes use
//! it: the metaballs' candidate lists per tile and the iso proxy's boxes
//! per band of rows.

/// Item indices grouped by bin.
#[derive(Debug, Clone, Default)]
pub(crate) struct Bins {
    /// Bin `b`'s items are `items[offsets[b]..offsets[b + 1]]`.
    offsets: Vec<usize>,
    items: Vec<u32>,
}

impl Bins {
    /// `n` bins of the items `0..count`; `bins_of(k, put)` calls `put(b)`
    /// for every bin `b` item `k` goes in (it is called twice per item and
    /// must name the same bins both times).
    pub fn build(n: usize, count: usize, bins_of: impl Fn(usize, &mut dyn FnMut(usize))) -> Self {
        let mut offsets = vec![0usize; n + 1];
        for k in 0..count {
            bins_of(k, &mut |b| offsets[b + 1] += 1);
        }
        for b in 0..n {
            offsets[b + 1] += offsets[b];
        }
        let mut cursor = offsets[..n].to_vec();
        let mut items = vec![0u32; offsets[n]];
        for k in 0..count {
            bins_of(k, &mut |b| {
                items[cursor[b]] = k as u32;
                cursor[b] += 1;
            });
        }
        Bins { offsets, items }
    }

    /// The items of bin `b`, in item order.
    #[inline]
    pub fn get(&self, b: usize) -> &[u32] {
        &self.items[self.offsets[b]..self.offsets[b + 1]]
    }

    /// Entries over all bins.
    pub fn entries(&self) -> usize {
        self.items.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_item_lands_in_its_bins_in_order() {
        let spans = [(0, 2), (1, 1), (3, 4), (0, 4), (2, 2)];
        let bins = Bins::build(5, spans.len(), |k, put| {
            for b in spans[k].0..=spans[k].1 {
                put(b);
            }
        });
        assert_eq!(bins.get(0), [0, 3]);
        assert_eq!(bins.get(1), [0, 1, 3]);
        assert_eq!(bins.get(2), [0, 3, 4]);
        assert_eq!(bins.get(3), [2, 3]);
        assert_eq!(bins.get(4), [2, 3]);
        assert_eq!(bins.entries(), 12);
    }
}
