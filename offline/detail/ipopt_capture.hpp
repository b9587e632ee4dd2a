#pragma once
/// Ipopt helpers shared by the equilibrium solvers (offline/equilibrium/equilibrium.cpp,
/// offline/equilibrium/free_equilibrium.cpp): one Ipopt run with the derivative checker's verdict
/// captured from Ipopt's messages. Includes Ipopt: for those .cpp files only.

#include <IpIpoptApplication.hpp>
#include <IpJournalist.hpp>
#include <IpTNLP.hpp>
#include <cstdarg>
#include <optional>
#include <string>

#include "offline/equilibrium/equilibrium.hpp"

namespace sinew::offline::detail {

// Collects what Ipopt prints in one category (the derivative checker's J_NLP messages).
class CaptureJournal : public Ipopt::Journal {
 public:
  CaptureJournal() : Ipopt::Journal("sinew-capture", Ipopt::J_NONE) {}
  const std::string& text() const { return text_; }

 protected:
  void PrintImpl(Ipopt::EJournalCategory, Ipopt::EJournalLevel, const char* str) override {
    text_ += str;
  }
  void PrintfImpl(Ipopt::EJournalCategory, Ipopt::EJournalLevel, const char* pformat,
                  va_list ap) override {
    char buffer[1024];
    va_list copy;
    va_copy(copy, ap);
    const int n = std::vsnprintf(buffer, sizeof(buffer), pformat, copy);
    va_end(copy);
    if (n > 0)
      text_.append(buffer, std::min<std::size_t>(static_cast<std::size_t>(n), sizeof(buffer) - 1));
  }
  void FlushBufferImpl() override {}

 private:
  std::string text_;
};

// The error count of Ipopt's derivative checker from its messages, if it reported one: its
// verdict line, or else the number of flagged entries (lines starting with "*").
std::optional<int> parse_derivative_test(const std::string& text);

struct IpoptRun {
  Ipopt::ApplicationReturnStatus status = Ipopt::Internal_Error;
  std::optional<int> derivative_test_errors;  ///< when the checker ran
  std::optional<int> iterations;
};

/// Runs problem with app, whose other options the caller has set: the derivative checker at the
/// start point when test is not kNone (its verdict read from a capturing journal), Initialize,
/// OptimizeTNLP. Exceptions become NonIpopt_Exception_Thrown.
IpoptRun run_ipopt(Ipopt::IpoptApplication& app, Ipopt::TNLP* problem, IpoptDerivativeTest test,
                   double test_tolerance, double test_perturbation);

}  // namespace sinew::offline::detail
