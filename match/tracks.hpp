// Building and cleaning tracks: union-find over verified feature matches that never puts two
// features of one image into a track, and pairwise epipolar voting that drops the observations a
// track's other images disagree with.
#pragma once

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <vector>

namespace photomill::match {

// One feature of one image: `image` indexes the image list, `feature` its FeatureSet.
struct FeatureRef {
  int image = 0;
  int feature = 0;
  bool operator==(const FeatureRef&) const = default;
  auto operator<=>(const FeatureRef&) const = default;
};

// A verified match between two features of different images; lower `cost` is better (the
// ratio-test distance ratio), so edges are joined best first.
struct MatchEdge {
  FeatureRef a, b;
  double cost = 0;
};

struct UnionStats {
  std::size_t edges = 0;
  std::size_t joined = 0;     // edges that merged two tracks
  std::size_t conflicts = 0;  // edges refused: the merged track would hold two features of one image
};

// Union-find (with path halving and union by size) over the features, taking the edges in order
// of increasing cost; an edge that would put two features of one image into one track is refused,
// which splits what a plain union-find would merge into a conflicting track. Returns the tracks
// (each sorted by image) with at least `min_length` (>= 2) features, ordered by their first feature.
std::vector<std::vector<FeatureRef>> build_tracks(std::vector<MatchEdge> edges, std::size_t min_length,
                                                  UnionStats* stats = nullptr);

// Pairwise voting within one track of n observations. `agree(i, j)` says whether observations i and
// j are consistent (true), inconsistent (false) or cannot be checked (nullopt, e.g. no epipolar
// geometry for that image pair). Repeatedly removes the observation with the most disagreements
// (ties: the one with fewer agreements, then the later one) until no pair disagrees; a pair that
// disagrees with nothing else to arbitrate (two observations left) removes both. Returns the
// indices kept, ascending; `verified[i]` is set for those that agree with at least one other.
std::vector<std::size_t> vote_track(std::size_t n,
                                    const std::function<std::optional<bool>(std::size_t, std::size_t)>& agree,
                                    std::vector<bool>* verified = nullptr);

}  // namespace photomill::match
