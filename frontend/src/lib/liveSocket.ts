// The /api/live WebSocket: reconnects by itself with backoff and resumes with ?since=<last seq seen>.
// Credentials never go in the URL: once open, the socket sends `authMessage()` (the login token as
// {"type": "auth", "token": ...}) as its first message.
import { Backoff } from "./backoff";
import type { LiveMessage } from "./liveState";

export interface SocketLike {
  onopen: ((ev: unknown) => void) | null;
  onmessage: ((ev: { data: unknown }) => void) | null;
  onclose: ((ev: unknown) => void) | null;
  onerror: ((ev: unknown) => void) | null;
  send(data: string): void;
  close(): void;
}

export type ConnectionState = "connecting" | "open" | "closed";

export interface LiveSocketOptions {
  url: (since: number | null) => string;
  lastSeq: () => number | null;
  /** The first message to send once open (the auth message), or null to send none. */
  authMessage?: () => string | null;
  onMessage: (message: LiveMessage) => void;
  onState?: (state: ConnectionState, retryInMs?: number) => void;
  makeSocket?: (url: string) => SocketLike;
  schedule?: (fn: () => void, ms: number) => unknown;
  cancel?: (handle: unknown) => void;
  backoff?: Backoff;
}

export class LiveSocket {
  private socket: SocketLike | null = null;
  private timer: unknown = null;
  private stopped = false;
  private readonly backoff: Backoff;

  constructor(private readonly options: LiveSocketOptions) {
    this.backoff = options.backoff ?? new Backoff();
  }

  start(): void {
    this.stopped = false;
    this.connect();
  }

  stop(): void {
    this.stopped = true;
    if (this.timer !== null) (this.options.cancel ?? ((h) => clearTimeout(h as number)))(this.timer);
    this.timer = null;
    const socket = this.socket;
    this.socket = null;
    if (socket) {
      socket.onclose = null;
      socket.close();
    }
    this.options.onState?.("closed");
  }

  private connect(): void {
    this.timer = null;
    const make = this.options.makeSocket ?? ((url: string) => new WebSocket(url) as unknown as SocketLike);
    const socket = make(this.options.url(this.options.lastSeq()));
    this.socket = socket;
    this.options.onState?.("connecting");
    socket.onopen = () => {
      const auth = this.options.authMessage?.() ?? null;
      if (auth !== null) socket.send(auth);
    };
    socket.onmessage = (ev) => {
      if (typeof ev.data !== "string") return;
      const message = JSON.parse(ev.data) as LiveMessage;
      if (message.type === "snapshot") {
        this.backoff.reset();
        this.options.onState?.("open");
      }
      this.options.onMessage(message);
    };
    socket.onclose = () => {
      if (this.socket !== socket || this.stopped) return;
      this.socket = null;
      const delay = this.backoff.next();
      this.options.onState?.("closed", delay);
      this.timer = (this.options.schedule ?? ((fn, ms) => setTimeout(fn, ms)))(() => this.connect(), delay);
    };
    socket.onerror = () => {
      /* onclose follows */
    };
  }
}
