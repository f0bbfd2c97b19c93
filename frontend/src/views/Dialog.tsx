// Modal dialogs: a box over a dimmed page that Escape or a click beside it closes, and a confirmation with
// Cancel (focused, so Enter does not destroy anything by accident) and the action.
import { useEffect, useRef, type ReactNode } from "react";

interface ModalProps {
  title: string;
  onClose: () => void;
  children: ReactNode;
  testId?: string;
  wide?: boolean;
}

export function Modal({ title, onClose, children, testId, wide }: ModalProps) {
  useEffect(() => {
    const onKey = (e: KeyboardEvent) => {
      if (e.key !== "Escape") return;
      e.stopImmediatePropagation(); // the dialog's Escape, not the page's
      onClose();
    };
    window.addEventListener("keydown", onKey, { capture: true });
    return () => window.removeEventListener("keydown", onKey, { capture: true });
  }, [onClose]);
  return (
    <div className="help" onClick={onClose} data-testid={testId ? `${testId}-backdrop` : undefined}>
      <div
        className={`card dialog${wide ? " wide" : ""}`}
        role="dialog"
        aria-modal="true"
        aria-label={title}
        data-testid={testId}
        onClick={(e) => e.stopPropagation()}
      >
        <h2>{title}</h2>
        {children}
      </div>
    </div>
  );
}

interface ConfirmProps {
  title: string;
  children: ReactNode;
  /** The action's button text, e.g. "Delete". */
  confirmLabel: string;
  danger?: boolean;
  onConfirm: () => void;
  onCancel: () => void;
}

export function ConfirmDialog({ title, children, confirmLabel, danger, onConfirm, onCancel }: ConfirmProps) {
  const cancel = useRef<HTMLButtonElement>(null);
  useEffect(() => cancel.current?.focus(), []);
  return (
    <Modal title={title} onClose={onCancel} testId="confirm-dialog">
      <div className="dialog-body">{children}</div>
      <div className="row dialog-buttons">
        <span className="spacer" />
        <button ref={cancel} data-testid="confirm-cancel" onClick={onCancel}>
          Cancel
        </button>
        <button className={danger ? "danger" : "primary"} data-testid="confirm-ok" onClick={onConfirm}>
          {confirmLabel}
        </button>
      </div>
    </Modal>
  );
}
