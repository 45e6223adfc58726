// rpyfmm Python bindings — one lock per bound object, so that several Python threads may call
// the same operator, plan or simulation (docs/safety-python.md).
//
// Every method of a stateful class runs under its object's lock (plus the lock of the bead
// operator it drives, for RigidBodies and RigidBodyDynamics): calls on one object are
// serialized, calls on different objects run in parallel. Deadlock rules:
//  * the GIL is never held while waiting for an object lock: a guard first tries the lock, and
//    releases the GIL before it blocks (the holder may need the GIL for a Python callback);
//  * two locks are taken together (std::lock), never one after the other;
//  * a call made from inside a callback that runs under the same lock (a force callback that
//    steps its own Simulation) raises NotSupportedError instead of waiting for itself; reads
//    (Access::read: properties, copies of state) are allowed there, since the call holding the
//    lock is paused in the callback.
//
// The locks live in a registry keyed by the C++ object's address; each entry is created on the
// first call and removed when the Python object dies (a capsule the object keeps alive).
#pragma once

#include <atomic>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <type_traits>
#include <unordered_map>
#include <utility>

#include "common.hpp"

namespace rpyfmm::python {

/// The lock of one bound object.
struct ObjectLock {
  std::mutex mutex;
  std::atomic<std::thread::id> owner{};  ///< the thread inside a call on the object, if any
};
using LockPtr = std::shared_ptr<ObjectLock>;

namespace detail {

struct LockRegistry {
  std::mutex mutex;
  std::unordered_map<const void*, LockPtr> locks;
};

inline LockRegistry& lock_registry() {
  static auto* registry = new LockRegistry();  // never destroyed: capsules may outlive static destruction
  return *registry;
}

/// What the capsule kept alive by the Python object holds: removes the entry when freed.
struct RegistryEntry {
  const void* key;
  LockPtr lock;
};

inline void forget_lock(void* p) noexcept {
  auto* entry = static_cast<RegistryEntry*>(p);
  {
    LockRegistry& r = lock_registry();
    const std::lock_guard<std::mutex> hold(r.mutex);
    auto it = r.locks.find(entry->key);
    if (it != r.locks.end() && it->second == entry->lock) r.locks.erase(it);
  }
  delete entry;
}

/// Makes `nurse` keep `patient` alive (nanobind's keep_alive, through its public annotation).
inline void keep_alive(nb::handle nurse, nb::handle patient) {
  // Created once and never freed (it may be needed until the interpreter ends).
  static const nb::handle attach = nb::cpp_function([](nb::handle, nb::handle) {}, nb::keep_alive<1, 2>()).release();
  attach(nurse, patient);
}

}  // namespace detail

/// The lock of the C++ object at `key`, whose Python object is `self()` (needed on first use only:
/// the entry is tied to the Python object's lifetime).
template <class FindSelf>
LockPtr lock_of(const void* key, FindSelf&& self) {
  detail::LockRegistry& r = detail::lock_registry();
  auto lock = std::make_shared<ObjectLock>();
  {
    const std::lock_guard<std::mutex> hold(r.mutex);
    auto [it, inserted] = r.locks.emplace(key, lock);
    if (!inserted) return it->second;
  }
  auto* entry = new detail::RegistryEntry{key, lock};
  nb::capsule capsule(entry, &detail::forget_lock);  // from here on, freeing it removes the entry
  nb::object owner = self();
  if (!owner.is_valid() || owner.is_none()) {
    fail(ErrorCode::invalid_input, "rpyfmm", "internal error: a bound object has no Python object");
  }
  detail::keep_alive(owner, capsule);
  return lock;
}

/// The lock of a bound object (keyed by its most-derived address: one lock per object whatever
/// base class a binding sees it as).
template <class T>
LockPtr lock_of(T& object) {
  const void* key = static_cast<const void*>(&object);
  if constexpr (std::is_polymorphic_v<T>) key = dynamic_cast<const void*>(&object);
  return lock_of(key, [&] { return nb::find(object); });
}

/// The lock of a second object a call on `object` uses; none by default (see rigid.cpp).
template <class T>
LockPtr inner_lock_of(const T&) {
  return nullptr;
}

enum class Access {
  call,  ///< anything that computes or changes state
  read,  ///< reads state only; allowed from a callback of a call on the same object
};

/// Holds an object's lock (and the inner one) for the duration of a binding.
class CallGuard {
 public:
  CallGuard(const std::string& where, Access access, LockPtr outer, LockPtr inner)
      : outer_(std::move(outer)), inner_(std::move(inner)) {
    const std::thread::id me = std::this_thread::get_id();
    if (outer_->owner == me || (inner_ && inner_->owner == me)) {
      if (access == Access::read) {  // the call holding the lock is paused in our callback
        outer_.reset();
        inner_.reset();
        return;
      }
      fail(ErrorCode::not_supported, where,
           "called from a callback that runs inside another call on the same object (or on the mobility "
           "operator it uses); call it after that call returns");
    }
    if (!try_lock()) {
      nb::gil_scoped_release release;  // never wait for the lock while holding the GIL
      lock();
    }
    outer_->owner = me;
    if (inner_) inner_->owner = me;
  }
  ~CallGuard() {
    if (!outer_) return;
    if (inner_) {
      inner_->owner = std::thread::id();
      inner_->mutex.unlock();
    }
    outer_->owner = std::thread::id();
    outer_->mutex.unlock();
  }
  CallGuard(const CallGuard&) = delete;
  CallGuard& operator=(const CallGuard&) = delete;

 private:
  bool try_lock() { return inner_ ? std::try_lock(outer_->mutex, inner_->mutex) == -1 : outer_->mutex.try_lock(); }
  void lock() {
    if (inner_) {
      std::lock(outer_->mutex, inner_->mutex);
    } else {
      outer_->mutex.lock();
    }
  }

  LockPtr outer_;
  LockPtr inner_;
};

/// A guard for a call on `object` (and on the operator it drives).
template <class T>
CallGuard guard(const std::string& where, T& object, Access access = Access::call) {
  return CallGuard(where, access, lock_of(object), inner_lock_of(object));
}

/// The binding fn(self, args...) of a method, run under self's lock: `locked("Class.method", fn)`.
/// fn is a function pointer (a capture-less lambda with a leading `+`).
template <Access A = Access::call, class R, class Self, class... Args>
auto locked(const char* where, R (*fn)(Self&, Args...)) {
  return [where, fn](Self& self, Args... args) -> R {
    const CallGuard hold = guard(where, self, A);
    return fn(self, std::forward<Args>(args)...);
  };
}

/// locked() for reads of state (properties).
template <class R, class Self, class... Args>
auto locked_read(const char* where, R (*fn)(Self&, Args...)) {
  return locked<Access::read>(where, fn);
}

}  // namespace rpyfmm::python
