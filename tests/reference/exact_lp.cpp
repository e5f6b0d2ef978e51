#include "tests/reference/exact_lp.h"

#include <cstddef>
#include <stdexcept>

namespace shadowcull::reference {

void ExactLp::add(const std::vector<Rational>& coefficients, Relation relation, const Rational& rhs) {
    if (int(coefficients.size()) != n_) throw std::invalid_argument("ExactLp::add: wrong number of coefficients");
    rows_.push_back({coefficients, relation, rhs});
}

namespace {

// The simplex tableau: rows T[i] (coefficients, then the right-hand side), basis B[i].
struct Tableau {
    std::vector<std::vector<Rational>> t;
    std::vector<int> basis;
    int columns = 0;  // without the right-hand side

    void pivot(size_t r, int j, std::vector<Rational>& objective) {
        std::vector<Rational>& row = t[r];
        const Rational p = row[size_t(j)];
        for (Rational& v : row) v /= p;
        for (size_t i = 0; i < t.size(); ++i) {
            if (i == r || t[i][size_t(j)] == 0) continue;
            const Rational f = t[i][size_t(j)];
            for (size_t k = 0; k < row.size(); ++k)
                if (row[k] != 0) t[i][k] -= f * row[k];
        }
        if (objective[size_t(j)] != 0) {
            const Rational f = objective[size_t(j)];
            for (size_t k = 0; k < row.size(); ++k)
                if (row[k] != 0) objective[k] -= f * row[k];
        }
        basis[r] = j;
    }

    // Maximises with reduced costs `objective` (size columns + 1), entering only columns
    // below `usable`. Bland's rule: the smallest entering index, and among the rows of the
    // least ratio the smallest basic variable. False when unbounded.
    bool run(std::vector<Rational>& objective, int usable) {
        for (;;) {
            int enter = -1;
            for (int j = 0; j < usable; ++j)
                if (objective[size_t(j)] > 0) {
                    enter = j;
                    break;
                }
            if (enter < 0) return true;
            long leave = -1;
            Rational best;
            for (size_t i = 0; i < t.size(); ++i) {
                const Rational& a = t[i][size_t(enter)];
                if (a <= 0) continue;
                const Rational ratio = t[i][size_t(columns)] / a;
                if (leave < 0 || ratio < best || (ratio == best && basis[i] < basis[size_t(leave)])) {
                    leave = long(i);
                    best = ratio;
                }
            }
            if (leave < 0) return false;
            pivot(size_t(leave), enter, objective);
        }
    }
};

}  // namespace

ExactLp::Outcome ExactLp::maximise(const std::vector<Rational>& objective) {
    if (int(objective.size()) != n_) throw std::invalid_argument("ExactLp::maximise: wrong number of coefficients");
    // Columns: the variables, one slack or surplus per inequality, one artificial per row
    // that has no slack to start from (after making every right-hand side >= 0).
    const size_t m = rows_.size();
    std::vector<Row> rows = rows_;
    int slacks = 0, artificials = 0;
    for (Row& r : rows) {
        if (r.b < 0) {
            for (Rational& v : r.a) v = -v;
            r.b = -r.b;
            if (r.rel == Relation::LessEqual) r.rel = Relation::GreaterEqual;
            else if (r.rel == Relation::GreaterEqual) r.rel = Relation::LessEqual;
        }
        if (r.rel != Relation::Equal) ++slacks;
        if (r.rel != Relation::LessEqual) ++artificials;
    }
    const int firstArtificial = n_ + slacks;
    Tableau T;
    T.columns = firstArtificial + artificials;
    T.t.assign(m, std::vector<Rational>(size_t(T.columns) + 1));
    T.basis.assign(m, -1);
    int s = n_, a = firstArtificial;
    for (size_t i = 0; i < m; ++i) {
        for (int j = 0; j < n_; ++j) T.t[i][size_t(j)] = rows[i].a[size_t(j)];
        T.t[i][size_t(T.columns)] = rows[i].b;
        if (rows[i].rel == Relation::LessEqual) {
            T.t[i][size_t(s)] = 1;
            T.basis[i] = s++;
        } else {
            if (rows[i].rel == Relation::GreaterEqual) T.t[i][size_t(s++)] = -1;
            T.t[i][size_t(a)] = 1;
            T.basis[i] = a++;
        }
    }
    // Phase 1: maximise minus the sum of the artificials.
    if (artificials > 0) {
        std::vector<Rational> phase1(size_t(T.columns) + 1);
        for (size_t i = 0; i < m; ++i)
            if (T.basis[i] >= firstArtificial)
                for (int j = 0; j <= T.columns; ++j)
                    if (j < firstArtificial || j == T.columns) phase1[size_t(j)] += T.t[i][size_t(j)];
        T.run(phase1, T.columns);  // bounded: the sum is >= 0
        for (size_t i = 0; i < m; ++i)
            if (T.basis[i] >= firstArtificial && T.t[i][size_t(T.columns)] != 0) return Outcome::Infeasible;
        // Drive the artificials (all at 0) out of the basis; a row with no other entry is
        // redundant and goes.
        for (size_t i = 0; i < T.t.size();) {
            if (T.basis[i] < firstArtificial) {
                ++i;
                continue;
            }
            int j = 0;
            while (j < firstArtificial && T.t[i][size_t(j)] == 0) ++j;
            if (j < firstArtificial) {
                T.pivot(i, j, phase1);
                ++i;
            } else {
                T.t.erase(T.t.begin() + long(i));
                T.basis.erase(T.basis.begin() + long(i));
            }
        }
    }
    // Phase 2: reduced costs c_j - c_B B^-1 A_j over the non-artificial columns.
    std::vector<Rational> cost(size_t(T.columns) + 1);
    for (int j = 0; j < n_; ++j) cost[size_t(j)] = objective[size_t(j)];
    for (size_t i = 0; i < T.t.size(); ++i) {
        const int b = T.basis[i];
        if (b >= n_ || objective[size_t(b)] == 0) continue;
        for (int j = 0; j <= T.columns; ++j) cost[size_t(j)] -= objective[size_t(b)] * T.t[i][size_t(j)];
    }
    if (!T.run(cost, firstArtificial)) return Outcome::Unbounded;
    x_.assign(size_t(n_), Rational(0));
    for (size_t i = 0; i < T.t.size(); ++i)
        if (T.basis[i] < n_) x_[size_t(T.basis[i])] = T.t[i][size_t(T.columns)];
    value_ = 0;
    for (int j = 0; j < n_; ++j) value_ += objective[size_t(j)] * x_[size_t(j)];
    return Outcome::Optimal;
}

}  // namespace shadowcull::reference
