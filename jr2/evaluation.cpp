#include <vkjr2/jr2/evaluation.hpp>
#include <vkjr2/runtime/error.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <map>
#include <sstream>
#include <tuple>

#include "internal/text_and_draws.hpp"

namespace vkjr2::jr2 {
namespace {

using ojson = nlohmann::ordered_json;

ojson number(double v) { return std::isfinite(v) ? ojson(v) : ojson(nullptr); }

ojson interval_json(const Interval& i) {
  return ojson{{"value", number(i.value)},
               {"ci95", {number(i.lo), number(i.hi)}},
               {"resamples", i.resamples}};
}

// An operating point: its value and interval, the target rate (`rate`:
// "far" or "fpir"), whether it is reported, from how many negatives, its
// threshold and the rate reached ("achieved_far"...).
ojson operating_json(const RateWithInterval& p, const std::string& rate, double target,
                     const char* negatives) {
  ojson x = interval_json(p.interval);
  x[rate] = target;
  x["reported"] = p.point.reported;
  x[negatives] = p.point.negatives;
  x["threshold"] = number(p.point.threshold);
  x["achieved_" + rate] = number(p.point.achieved);
  return x;
}

std::string percent(double v) {
  if (!std::isfinite(v)) return "—";
  char b[32];
  std::snprintf(b, sizeof b, "%.1f", 100 * v);
  return b;
}

std::string with_ci(const Interval& i) {
  if (!std::isfinite(i.value)) return "—";
  return percent(i.value) + " [" + percent(i.lo) + ", " + percent(i.hi) + "]";
}

// "24.31 [23.10, 25.62]" in the given format; "—" when undefined.
std::string plain_ci(const Interval& i, const char* format) {
  if (!std::isfinite(i.value)) return "—";
  const auto f = [&](double v) {
    char b[32];
    std::snprintf(b, sizeof b, format, v);
    return std::string(b);
  };
  return f(i.value) + " [" + f(i.lo) + ", " + f(i.hi) + "]";
}

std::string far_label(double f) {
  char b[32];
  std::snprintf(b, sizeof b, "%g", f);
  return b;
}

}  // namespace

Evaluation evaluate(std::vector<std::string> gallery, std::string split,
                    std::vector<ProbeRecord> records, const EvaluationOptions& o) {
  Evaluation e;
  e.gallery = std::move(gallery);
  e.split = std::move(split);
  e.options = o;
  e.records = std::move(records);
  for (std::size_t i = 0; i < e.records.size(); ++i) {
    const ProbeRecord& r = e.records[i];
    if (r.scores.size() != e.gallery.size() || r.mate >= int(e.gallery.size()) ||
        r.mated != (r.mate >= 0)) {
      throw InvalidArgument("evaluate",
                            "record " + std::to_string(i) + " (" + r.file + ") has " +
                                std::to_string(r.scores.size()) + " scores and mate " +
                                std::to_string(r.mate) + " for a gallery of " +
                                std::to_string(e.gallery.size()),
                            "score every probe against the whole gallery");
    }
  }
  // Rows in first-seen order.
  std::vector<std::tuple<std::string, std::string, std::string>> keys;
  std::map<std::tuple<std::string, std::string, std::string>, std::vector<std::size_t>> groups;
  for (std::size_t i = 0; i < e.records.size(); ++i) {
    const ProbeRecord& r = e.records[i];
    auto key = std::make_tuple(r.method, r.align, r.strength);
    auto [it, fresh] = groups.try_emplace(key);
    if (fresh) keys.push_back(key);
    it->second.push_back(i);
  }
  for (const auto& key : keys) {
    RowMetrics row;
    std::tie(row.method, row.align, row.strength) = key;
    std::vector<Search> searches;
    std::vector<int> units;
    std::map<std::string, int> unit_of;
    for (std::size_t i : groups[key]) {
      const ProbeRecord& r = e.records[i];
      searches.push_back({r.scores, r.mate});
      units.push_back(unit_of.try_emplace(r.identity, int(unit_of.size())).first->second);
      ++row.probes;
      row.mated += r.mated ? 1 : 0;
      row.acquired += r.acquired ? 1 : 0;
      row.frames += std::size_t(r.frames);
      row.single_scale += std::size_t(r.single_scale);
      row.multi_scale += std::size_t(r.multi_scale);
      row.tracked += std::size_t(r.tracked);
    }
    row.nonmated = row.probes - row.mated;
    row.identities = unit_of.size();
    check_searches(searches, "evaluate");
    const VerificationScores v = verification_scores(searches);
    if (!v.genuine.empty() && !v.impostor.empty()) row.roc = roc_curve(v.genuine, v.impostor);
    for (double far : o.fars) {
      RateWithInterval t;
      t.point = tar_at_far(v.genuine, v.impostor, far);
      t.interval = bootstrap(
          searches, units,
          [far](std::span<const Search> s) {
            const VerificationScores vs = verification_scores(s);
            return tar_at_far(vs.genuine, vs.impostor, far).value;
          },
          o.bootstrap);
      row.tar.push_back(t);
    }
    const std::size_t max_rank = std::min<std::size_t>(20, e.gallery.size());
    row.cmc = cmc(searches, max_rank);
    for (std::size_t k : o.ranks) {
      row.rank.push_back(bootstrap(
          searches, units, [k](std::span<const Search> s) { return cmc(s, k).back(); },
          o.bootstrap));
    }
    for (double p : o.fpirs) {
      RateWithInterval f;
      f.point = fnir_at_fpir(searches, p, o.fnir_max_rank);
      const std::size_t r = o.fnir_max_rank;
      f.interval = bootstrap(
          searches, units,
          [p, r](std::span<const Search> s) { return fnir_at_fpir(s, p, r).value; }, o.bootstrap);
      row.fnir.push_back(f);
    }
    if (row.nonmated > 0 && row.mated > 0) row.open_set = open_set_curve(searches, o.fnir_max_rank);
    // Image quality: the mean over the probes (of the drawn probes, in the
    // bootstrap) that have a figure.
    const std::vector<std::size_t>& members = groups[key];
    const auto mean_of = [&](double ProbeRecord::*field) {
      return [&, field](std::span<const std::size_t> drawn) {
        double sum = 0;
        std::size_t count = 0;
        for (std::size_t k : drawn) {
          const double x = e.records[members[k]].*field;
          if (std::isfinite(x)) {
            sum += x;
            ++count;
          }
        }
        return count == 0 ? std::numeric_limits<double>::quiet_NaN() : sum / double(count);
      };
    };
    row.psnr_db = bootstrap_items(units, mean_of(&ProbeRecord::psnr_db), o.bootstrap);
    row.ssim = bootstrap_items(units, mean_of(&ProbeRecord::ssim), o.bootstrap);
    row.seconds = bootstrap_items(units, mean_of(&ProbeRecord::seconds), o.bootstrap);
    for (std::size_t i : members) {
      row.gated += e.records[i].restored >= 0 ? 1 : 0;
      row.restored += e.records[i].restored > 0 ? 1 : 0;
    }
    e.rows.push_back(std::move(row));
  }
  return e;
}

std::string results_json(const Evaluation& e, const std::string& setup_json) {
  ojson j;
  j["setup"] = ojson::parse(setup_json);
  j["split"] = e.split;
  j["gallery"] = e.gallery;
  j["bootstrap"] = {{"resamples", e.options.bootstrap.resamples},
                    {"level", e.options.bootstrap.level},
                    {"seed", e.options.bootstrap.seed},
                    {"unit", "identity, then probe"}};
  j["fnir_max_rank"] = e.options.fnir_max_rank;
  j["rows"] = ojson::array();
  for (const RowMetrics& r : e.rows) {
    ojson row{{"method", r.method},     {"align", r.align},          {"strength", r.strength},
              {"probes", r.probes},     {"mated", r.mated},          {"nonmated", r.nonmated},
              {"acquired", r.acquired}, {"identities", r.identities}};
    row["detection"] = {{"frames", r.frames},
                        {"single_scale", r.single_scale},
                        {"multi_scale", r.multi_scale},
                        {"tracked", r.tracked}};
    ojson tar = ojson::array();
    for (std::size_t i = 0; i < r.tar.size(); ++i) {
      tar.push_back(operating_json(r.tar[i], "far", e.options.fars[i], "impostors"));
    }
    row["tar_at_far"] = tar;
    ojson ranks = ojson::array();
    for (std::size_t i = 0; i < r.rank.size(); ++i) {
      ojson x = interval_json(r.rank[i]);
      x["rank"] = e.options.ranks[i];
      x["trivial"] = e.options.ranks[i] >= e.gallery.size();
      ranks.push_back(x);
    }
    row["rank"] = ranks;
    ojson fnir = ojson::array();
    for (std::size_t i = 0; i < r.fnir.size(); ++i) {
      ojson x = operating_json(r.fnir[i], "fpir", e.options.fpirs[i], "nonmated_searches");
      x["tpir"] = number(1.0 - r.fnir[i].point.value);
      fnir.push_back(x);
    }
    row["fnir_at_fpir"] = fnir;
    row["psnr_db"] = interval_json(r.psnr_db);
    row["ssim"] = interval_json(r.ssim);
    row["seconds_per_probe"] = interval_json(r.seconds);
    if (r.gated > 0) {
      row["gate"] = {{"probes", r.gated},
                     {"restored", r.restored},
                     {"skipped_share", double(r.gated - r.restored) / double(r.gated)}};
    }
    ojson roc = ojson::array();
    for (const RocPoint& p : r.roc) roc.push_back({number(p.threshold), p.far, p.tar});
    row["roc"] = {{"columns", {"threshold", "far", "tar"}}, {"points", roc}};
    row["cmc"] = r.cmc;
    ojson det = ojson::array();
    for (const OpenSetPoint& p : r.open_set) det.push_back({number(p.threshold), p.fpir, p.fnir});
    row["fnir_fpir"] = {{"columns", {"threshold", "fpir", "fnir"}}, {"points", det}};
    j["rows"].push_back(row);
  }
  return j.dump(1) + "\n";
}

std::string report_markdown(const Evaluation& e, const std::string& preamble) {
  const EvaluationOptions& o = e.options;
  std::ostringstream md;
  md << preamble << "\n";
  md << "| method | align | strength | probes (mated / non-mated) | face found: 1 size / "
        "multi-size / track |";
  for (double f : o.fars) md << " TAR@FAR " << far_label(f) << " |";
  for (std::size_t k : o.ranks) md << " Rank-" << k << " |";
  for (double p : o.fpirs) md << " FNIR@FPIR " << far_label(p) << " |";
  md << " PSNR (dB) | SSIM | s / probe | skipped |";
  md << "\n|---|---|---|---|---|";
  for (std::size_t i = 0; i < o.fars.size() + o.ranks.size() + o.fpirs.size() + 4; ++i)
    md << "---|";
  md << "\n";
  std::vector<std::string> notes;
  for (const RowMetrics& r : e.rows) {
    const auto share = [&](std::size_t n) {
      return r.frames == 0 ? std::string("—") : percent(double(n) / double(r.frames));
    };
    md << "| " << r.method << " | " << r.align << " | " << r.strength << " | " << r.probes << " ("
       << r.mated << " / " << r.nonmated << ") | " << share(r.single_scale) << " / "
       << share(r.multi_scale) << " / " << share(r.tracked) << " |";
    for (const RateWithInterval& t : r.tar) {
      md << " " << (t.point.reported ? with_ci(t.interval) : "n/a") << " |";
    }
    for (std::size_t i = 0; i < r.rank.size(); ++i) {
      md << " " << (o.ranks[i] >= e.gallery.size() ? std::string("n/a") : with_ci(r.rank[i]))
         << " |";
    }
    for (const RateWithInterval& f : r.fnir) {
      md << " " << (f.point.reported ? with_ci(f.interval) : "n/a") << " |";
    }
    md << " " << plain_ci(r.psnr_db, "%.2f") << " | " << plain_ci(r.ssim, "%.3f") << " | "
       << plain_ci(r.seconds, "%.2f") << " | "
       << (r.gated == 0 ? std::string("—")
                        : percent(double(r.gated - r.restored) / double(r.gated)))
       << " |\n";
  }
  md << "\nAll figures but PSNR and SSIM are percentages; every one has a bootstrap 95 % interval ("
     << o.bootstrap.resamples << " resamples of identities, then of each identity's probes; seed "
     << o.bootstrap.seed << ").\n";
  if (!e.rows.empty()) {
    const RowMetrics& r = e.rows.front();
    md << "\nWhy some cells are n/a: a FAR of f needs at least 1/f impostor pairs (this split has "
       << (r.tar.empty() ? 0 : r.tar.front().point.negatives)
       << " per row); an FPIR of p needs at least 1/p non-mated searches (it has " << r.nonmated
       << "); Rank-k is 100 % by construction when k ≥ the gallery's " << e.gallery.size()
       << " identities.\n";
  }
  md << "\nFace found: the share of sampled frames in which the probe's face was found by the "
        "detector at one input size, at several pooled, and with the track (a weaker "
        "detection where the face was in the other frames). Only tracked frames are described.\n"
        "PSNR and SSIM: the sampled frames against the probe's clean clip (8-bit range), "
        "the mean over a probe's frames, then over the probes.\n"
        "s / probe: the method's wall time per probe video (decoding excluded). Skipped: the "
        "share of probes a gated method's gate left unrestored (— for the others).\n"
        "FNIR is at rank "
     << o.fnir_max_rank
     << " (the mate must be the top candidate and score above the threshold). A probe without any "
        "face found scores below every gallery identity (a miss, never a false alarm).\n";
  return md.str();
}

std::string scores_csv(const Evaluation& e) {
  std::ostringstream out;
  out << "method,align,strength,probe,gallery_identity,score,mated\n";
  char score[40];
  for (const ProbeRecord& r : e.records) {
    for (std::size_t g = 0; g < r.scores.size(); ++g) {
      std::snprintf(score, sizeof score, "%.9f", r.scores[g]);
      out << detail::csv_field(r.method) << "," << detail::csv_field(r.align) << ","
          << detail::csv_field(r.strength) << "," << detail::csv_field(r.file) << ","
          << detail::csv_field(e.gallery[g]) << "," << score << "," << (int(g) == r.mate ? 1 : 0)
          << "\n";
    }
  }
  return out.str();
}

}  // namespace vkjr2::jr2
