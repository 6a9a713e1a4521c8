// Track building and voting (see tracks.hpp).
#include "match/tracks.hpp"

#include <algorithm>
#include <map>
#include <numeric>

namespace photomill::match {

std::vector<std::vector<FeatureRef>> build_tracks(std::vector<MatchEdge> edges, std::size_t min_length,
                                                  UnionStats* stats) {
  // Dense node numbering.
  std::map<FeatureRef, std::size_t> id;
  std::vector<FeatureRef> node;
  auto node_of = [&](const FeatureRef& f) {
    const auto [it, fresh] = id.emplace(f, node.size());
    if (fresh) node.push_back(f);
    return it->second;
  };
  std::stable_sort(edges.begin(), edges.end(), [](const MatchEdge& x, const MatchEdge& y) { return x.cost < y.cost; });
  std::vector<std::pair<std::size_t, std::size_t>> links;
  links.reserve(edges.size());
  for (const auto& e : edges) links.emplace_back(node_of(e.a), node_of(e.b));

  std::vector<std::size_t> parent(node.size());
  std::iota(parent.begin(), parent.end(), std::size_t{0});
  // Images of each root's set, sorted: the conflict check intersects two of them.
  std::vector<std::vector<int>> images(node.size());
  for (std::size_t k = 0; k < node.size(); ++k) images[k] = {node[k].image};
  auto find = [&](std::size_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  UnionStats s;
  s.edges = links.size();
  for (const auto& [u, v] : links) {
    std::size_t ru = find(u), rv = find(v);
    if (ru == rv) continue;
    std::vector<int>& iu = images[ru];
    std::vector<int>& iv = images[rv];
    std::vector<int> merged;
    merged.reserve(iu.size() + iv.size());
    std::set_union(iu.begin(), iu.end(), iv.begin(), iv.end(), std::back_inserter(merged));
    if (merged.size() != iu.size() + iv.size()) {
      ++s.conflicts;
      continue;
    }
    if (iu.size() < iv.size()) std::swap(ru, rv);
    parent[rv] = ru;
    images[ru] = std::move(merged);
    images[rv].clear();
    ++s.joined;
  }
  std::map<std::size_t, std::vector<FeatureRef>> sets;
  for (std::size_t k = 0; k < node.size(); ++k) sets[find(k)].push_back(node[k]);
  std::vector<std::vector<FeatureRef>> tracks;
  for (auto& [root, members] : sets) {
    if (members.size() < std::max<std::size_t>(min_length, 2)) continue;
    std::sort(members.begin(), members.end());
    tracks.push_back(std::move(members));
  }
  // Each track is sorted and a feature belongs to one track only: order by the first feature.
  std::sort(tracks.begin(), tracks.end(), [](const auto& x, const auto& y) { return x.front() < y.front(); });
  if (stats) *stats = s;
  return tracks;
}

std::vector<std::size_t> vote_track(std::size_t n,
                                    const std::function<std::optional<bool>(std::size_t, std::size_t)>& agree,
                                    std::vector<bool>* verified) {
  // Cache the pairwise verdicts once.
  std::vector<std::optional<bool>> verdict(n * n);
  for (std::size_t i = 0; i < n; ++i) {
    for (std::size_t j = i + 1; j < n; ++j) verdict[i * n + j] = verdict[j * n + i] = agree(i, j);
  }
  std::vector<bool> alive(n, true);
  std::size_t remaining = n;
  for (;;) {
    std::size_t worst = n;
    int worst_bad = 0, worst_good = 0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!alive[i]) continue;
      int bad = 0, good = 0;
      for (std::size_t j = 0; j < n; ++j) {
        if (j == i || !alive[j] || !verdict[i * n + j]) continue;
        (*verdict[i * n + j] ? good : bad) += 1;
      }
      if (bad > 0 && (bad > worst_bad || (bad == worst_bad && good <= worst_good))) {
        worst = i;
        worst_bad = bad;
        worst_good = good;
      }
    }
    if (worst == n) break;
    if (remaining == 2) {
      std::fill(alive.begin(), alive.end(), false);  // two that disagree: neither can be trusted
      break;
    }
    alive[worst] = false;
    --remaining;
  }
  std::vector<std::size_t> kept;
  if (verified) verified->assign(n, false);
  for (std::size_t i = 0; i < n; ++i) {
    if (!alive[i]) continue;
    kept.push_back(i);
    if (!verified) continue;
    for (std::size_t j = 0; j < n; ++j) {
      if (j != i && alive[j] && verdict[i * n + j] == true) (*verified)[i] = true;
    }
  }
  return kept;
}

}  // namespace photomill::match
