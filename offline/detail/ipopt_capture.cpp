#include "offline/detail/ipopt_capture.hpp"

#include <IpSolveStatistics.hpp>
#include <cstdio>

namespace sinew::offline::detail {

std::optional<int> parse_derivative_test(const std::string& text) {
  const std::string key = "Derivative checker detected ";
  const std::size_t at = text.find(key);
  int errors = 0;
  if (at != std::string::npos && std::sscanf(text.c_str() + at + key.size(), "%d", &errors) == 1) {
    return errors;
  }
  if (text.find("No errors detected by derivative checker") != std::string::npos) return 0;
  int flagged = 0;
  for (std::size_t p = 0; p < text.size(); p = text.find('\n', p) + 1) {
    if (text[p] == '*') ++flagged;
    if (text.find('\n', p) == std::string::npos) break;
  }
  if (flagged > 0) return flagged;
  return std::nullopt;
}

IpoptRun run_ipopt(Ipopt::IpoptApplication& app, Ipopt::TNLP* problem, IpoptDerivativeTest test,
                   double test_tolerance, double test_perturbation) {
  IpoptRun run;
  Ipopt::SmartPtr<CaptureJournal> journal;
  try {
    if (test != IpoptDerivativeTest::kNone) {
      Ipopt::SmartPtr<Ipopt::OptionsList> o = app.Options();
      o->SetStringValue("derivative_test",
                        test == IpoptDerivativeTest::kFirstOrder ? "first-order" : "second-order");
      o->SetNumericValue("derivative_test_tol", test_tolerance);
      o->SetNumericValue("derivative_test_perturbation", test_perturbation);
      o->SetNumericValue("point_perturbation_radius", 0.0);  // check at the start point itself
    }
    run.status = app.Initialize();
    if (run.status == Ipopt::Solve_Succeeded) {
      if (test != IpoptDerivativeTest::kNone) {
        journal = new CaptureJournal();
        // Ipopt 3.11.9 prints the checker's verdict above J_SUMMARY: capture up to J_ITERSUMMARY.
        journal->SetAllPrintLevels(Ipopt::J_ITERSUMMARY);
        app.Jnlst()->AddJournal(Ipopt::GetRawPtr(journal));
      }
      run.status = app.OptimizeTNLP(problem);
    }
  } catch (...) {
    run.status = Ipopt::NonIpopt_Exception_Thrown;
  }
  if (Ipopt::IsValid(journal)) run.derivative_test_errors = parse_derivative_test(journal->text());
  if (Ipopt::IsValid(app.Statistics())) run.iterations = app.Statistics()->IterationCount();
  return run;
}

}  // namespace sinew::offline::detail
