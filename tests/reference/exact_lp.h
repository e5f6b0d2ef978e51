// A small dense linear-program solver in exact rational arithmetic (GMP's mpq_class), for
// the test reference (tests/reference/exact_reference.h): two-phase primal simplex with
// Bland's rule, which never cycles, so every answer is exact and every run ends. Meant for
// a few dozen variables and rows; nothing here is tuned for size.
//
// Written for the tests alone: it shares nothing with geometry/ (which clips polygons in
// CGAL's lazy kernel), so that the reference's "no pair exists" is decided by another
// method on another number type.
#pragma once

#include <vector>

#include <gmpxx.h>

namespace shadowcull::reference {

using Rational = mpq_class;

class ExactLp {
public:
    enum class Relation { LessEqual, Equal, GreaterEqual };
    enum class Outcome { Optimal, Infeasible, Unbounded };

    // Variables are numbered from 0 and are all >= 0.
    explicit ExactLp(int variables) : n_(variables) {}
    int variables() const { return n_; }
    // sum_j coefficients[j] x_j (relation) rhs; `coefficients` has variables() entries.
    void add(const std::vector<Rational>& coefficients, Relation relation, const Rational& rhs);
    // Maximises sum_j objective[j] x_j. Exact. On Optimal, value() and solution() hold the
    // optimum and an optimal vertex.
    Outcome maximise(const std::vector<Rational>& objective);
    const Rational& value() const { return value_; }
    const std::vector<Rational>& solution() const { return x_; }
    int rows() const { return int(rows_.size()); }

private:
    struct Row {
        std::vector<Rational> a;
        Relation rel;
        Rational b;
    };
    int n_;
    std::vector<Row> rows_;
    Rational value_;
    std::vector<Rational> x_;
};

}  // namespace shadowcull::reference
