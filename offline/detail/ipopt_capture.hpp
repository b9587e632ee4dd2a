#pragma once
/// Ipopt helpers shared by the equilibrium solvers (offline/equilibrium.cpp,
/// offline/free_equilibrium.cpp): a journal that captures Ipopt's messages, and the error count
/// of Ipopt's derivative checker read from them. Includes Ipopt: for those .cpp files only.

#include <IpJournalist.hpp>
#include <cstdarg>
#include <optional>
#include <string>

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

}  // namespace sinew::offline::detail
