// What a contact sub-model keeps from one step to the next, declared by the sub-model: one vector
// per declared field and contact entry, the value on the entry's owner (the partner's is its
// negative, so a pair's history is kept by ids on the smaller id, integrate/contact_history.hpp).
// From the declarations follow the history arrays, their carry across rebuilds, the checkpoint
// and the device's fields.
#pragma once

namespace crushdem {

struct HistoryField {
  const char* name;  // short array name, as in checkpoints and device fields: "ft" (ft_x, ...)
  const char* what;  // what it holds, with its unit
};

}  // namespace crushdem
