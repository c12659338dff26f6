// GLSL mirror of core/lists/segment_list.h (Alg. 5 merge rules, t_seen guard, overflow), line by line. Any
// change there must be made here too; the GL tests compare both builders pixel for pixel.
// The lists of the current band live in sl_events: list p holds sl_events[p * capacity ...].
// The interlock program defines SL_EVENTS_QUALIFIER as `coherent`: one fragment's writes must be seen
// by the next fragment of the pixel entering the critical section.

#ifndef SL_EVENTS_QUALIFIER
#define SL_EVENTS_QUALIFIER
#endif
layout(std430, binding = 3) SL_EVENTS_QUALIFIER buffer SlEvents {
  SlRayEvent sl_events[];
};

const uint SL_LIST_OVERFLOW = 0x80000000u;  // kListOverflow
const uint SL_NO_RULE = 0xFFFFFFFFu;

uint sl_event_type(SlRayEvent e) { return e.bits & 0xFFu; }
uint sl_event_class(SlRayEvent e) { return (e.bits >> 8) & 0xFFu; }
SlRayEvent sl_make_event(float t, uint type, uint cls) { return SlRayEvent(t, type | (cls << 8)); }
bool sl_needs_sampling(uint c) { return c == SL_NONEMPTY || c == SL_UNKNOWN; }

// detail::absorb_short_gap: `next` starts a NON_EMPTY/UNKNOWN segment; an EMPTY segment before it
// shorter than eps is absorbed (the conservative form of Alg. 5 lines 16-25).
uint sl_absorb_short_gap(uint base, uint n, SlRayEvent next, float eps) {
  if (!(eps > 0.0) || n == 0u || !sl_needs_sampling(sl_event_class(next))) return SL_NO_RULE;
  SlRayEvent gap = sl_events[base + n - 1u];
  precise float gap_len = next.t - gap.t;
  if (sl_event_class(gap) != SL_EMPTY || !(gap_len < eps)) return SL_NO_RULE;
  gap.bits = sl_event_type(next) | (sl_event_class(next) << 8);  // gap.cls = next.cls; gap.type = next.type
  sl_events[base + n - 1u] = gap;
  if (n >= 2u && sl_event_class(sl_events[base + n - 2u]) == sl_event_class(gap)) --n;
  return n;
}

// add_event: one event onto the tail of list `base`.
void sl_add_event(uint base, inout uint count_word, inout float t_seen, uint capacity, float t, uint type, uint cls,
                  float eps) {
  if ((count_word & SL_LIST_OVERFLOW) != 0u) return;  // overflowed: the tail is already conservative
  uint n = count_word;
  // Monotonicity guard (see segment_list.h): an earlier t is coincident with the latest depth seen.
  if (t < t_seen) {
    t = t_seen;
  } else {
    t_seen = t;
  }
  if (n > 0u && sl_events[base + n - 1u].t == t) {  // isEqual(eventPrev.depth, depth): same-depth rules
    SlRayEvent prev = sl_events[base + n - 1u];
    if (sl_event_type(prev) == type) {
      // Alg. 5, rule 1 (2x ENTRY or 2x EXIT): keep the last only...
      prev.bits = sl_event_type(prev) | (cls << 8);
      sl_events[base + n - 1u] = prev;
      // ...and drop it if it now repeats the class before it (minimality, DESIGN.md "Ray segment lists").
      if (n >= 2u && sl_event_class(sl_events[base + n - 2u]) == cls) {
        --n;
      } else {
        const uint m = sl_absorb_short_gap(base, n - 1u, prev, eps);
        if (m != SL_NO_RULE) n = m;
      }
      count_word = n;
      return;
    }
    if (type == SL_EXIT) {  // Alg. 5, rule 2: ENTRY then EXIT, delete both
      count_word = n - 1u;
      return;
    }
    if (n >= 2u && sl_event_class(sl_events[base + n - 2u]) == cls) {  // Alg. 5, rule 3
      count_word = n - 1u;
      return;
    }
  }
  if (n > 0u && sl_event_class(sl_events[base + n - 1u]) == cls) return;  // no-op event
  const SlRayEvent e = sl_make_event(t, type, cls);  // made only now that it is kept
  const uint m = sl_absorb_short_gap(base, n, e, eps);
  if (m != SL_NO_RULE) {
    count_word = m;
    return;
  }
  if (n >= capacity) {
    // Full: keep what we have and make the open tail conservative (it extends to the volume exit).
    if (n > 0u && sl_event_class(sl_events[base + n - 1u]) == SL_EMPTY) {
      sl_events[base + n - 1u].bits = sl_event_type(sl_events[base + n - 1u]) | (SL_NONEMPTY << 8);
    }
    count_word = n | SL_LIST_OVERFLOW;
    return;
  }
  sl_events[base + n] = e;
  count_word = n + 1u;
}
